"""Symbolic success of a trained planner (``muble train trainer=planner``) per SHOP-VRB2 template, on scenes of a
seed it was not trained on (the validation stream of that seed: ``muble_plugins.learned.planner.scene_for``), with
the oracle on the same episodes beside it.

    python benchmarks/learned_planner.py CHECKPOINT [SEED] [SCENES]      # defaults: seed 7, 300 scenes
"""
from __future__ import annotations

import json
import os
import sys
import time

os.environ.setdefault("MUJOCO_GL", "egl")


def main(argv: list[str]) -> dict:
    import torch

    torch.set_num_threads(1)
    from muble_plugins.agents.oracle import OracleAgent
    from muble_plugins.learned.agent import LearnedPlannerAgent
    from muble_plugins.learned.planner import instructions_for, scene_for, symbolic_success

    checkpoint = argv[0]
    seed = int(argv[1]) if len(argv) > 1 else 7
    scenes = int(argv[2]) if len(argv) > 2 else 300
    episodes = [(instruction, scene) for index in range(scenes) for scene in [scene_for(seed, index, True)]
                for instruction in instructions_for(scene, seed, index, True)]
    start = time.perf_counter()
    learned = symbolic_success(LearnedPlannerAgent(checkpoint=checkpoint), episodes)
    learned_s = time.perf_counter() - start
    oracle = symbolic_success(OracleAgent(), episodes)
    solved = sum(v[0] for v in learned.values())
    out = {"checkpoint": checkpoint, "seed": seed, "scenes": scenes, "episodes": len(episodes),
           "learned_success": solved / len(episodes), "learned_seconds": round(learned_s, 1),
           "per_template": {k: {"learned": f"{v[0]}/{v[1]}", "oracle": f"{oracle[k][0]}/{oracle[k][1]}"}
                            for k, v in learned.items()}}
    for k, v in out["per_template"].items():
        print(f"{k:24s} learned {v['learned']:>8s}   oracle {v['oracle']:>8s}")
    return out


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1:])))
