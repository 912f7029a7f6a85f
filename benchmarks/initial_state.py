"""How far generated scenes move under the initial-state check, against its tolerances, and what the check costs.

Each scene comes from the configured scene generator (``muble.episode.components.scene_generator``, the ``eval`` config), is
built into a ``TabletopEnv`` and settled and checked by ``muble.sim.initial_state.settle_and_check``. Reported:
how many pass, the largest displacement, rotation and resting contact depth over all objects, and the wall time of
the check per scene. Goal: every generated scene passes with its largest displacement at most a tenth of
``SETTLED_DISPLACEMENT`` (``muble.stage.rest``).

    python benchmarks/initial_state.py [--seed 0] [--scenes 100] [overrides ...]   # e.g. objects=ycb robot=UR5e
"""
from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")


def main() -> None:
    from omegaconf import OmegaConf

    from muble.app.config import compose
    from muble.episode.components import scene_generator
    from muble.core.errors import InitialStateError
    from muble.evaluation.episodes import build_components
    from muble.sim.build import object_models
    from muble.sim.env import TabletopEnv
    from muble.sim.initial_state import MAX_PENETRATION, settle_and_check
    from muble.stage.rest import SETTLED_DISPLACEMENT, SETTLED_TURN

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scenes", type=int, default=100)
    parser.add_argument("overrides", nargs="*", help="Hydra overrides of the eval config")
    args = parser.parse_args()

    cfg = compose("eval", [f"seed={args.seed}", "output.dir=/tmp", "dataset.root=/tmp", *args.overrides])
    components = build_components(OmegaConf.to_container(cfg, resolve=True))
    robot = OmegaConf.to_container(cfg.robot, resolve=True)
    generator = scene_generator(cfg, components["object_set"])
    moved, turned, depth, seconds, failed, objects = [], [], [], [], [], 0
    try:
        for index in range(args.scenes):
            scene = generator.generate(index)
            env = TabletopEnv(scene, object_models(scene, components["object_set"], cfg.objects.name), robot)
            objects += len(scene.objects)
            start = time.perf_counter()
            try:
                report = settle_and_check(env)
            except InitialStateError as e:
                failed.append({"scene": index, "error": str(e)})
                continue
            finally:
                seconds.append(time.perf_counter() - start)
            moved.append(report.max_displacement)
            turned.append(report.max_rotation)
            depth.append(report.max_penetration)
    finally:
        generator.close()
    largest = max(moved, default=0.0)
    print(json.dumps({
        "benchmark": "initial_state", "metric": "largest settle displacement", "value": round(largest * 1000, 3),
        "unit": "mm", "goal": SETTLED_DISPLACEMENT * 1000 / 10, "scenes": args.scenes, "objects": objects,
        "passed": args.scenes - len(failed), "failed": failed, "tolerance_mm": SETTLED_DISPLACEMENT * 1000,
        "largest_rotation_deg": round(max(turned, default=0.0), 3), "tolerance_deg": SETTLED_TURN,
        "deepest_contact_mm": round(max(depth, default=0.0) * 1000, 3), "penetration_limit_mm": MAX_PENETRATION * 1000,
        "check_s_median": round(float(np.median(seconds)), 3), "check_s_max": round(float(np.max(seconds)), 3),
        "overrides": args.overrides, "seed": args.seed,
    }))


if __name__ == "__main__":
    main()
