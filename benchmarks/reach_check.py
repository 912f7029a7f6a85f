"""The scene generator's reach check: seconds per layout on the recorded candidate layouts of
``tests/generation/data/reach_decisions.json.gz`` (300 generated scenes, the rejected layouts included), against
the check of an earlier revision (default: 59a4fc7, before it was made faster) timed on the same layouts in the
same run, with both decisions compared to the recorded ones.

    python benchmarks/reach_check.py [--layouts 40] [--baseline-rev 59a4fc7]

The baseline runs in a subprocess from ``git archive`` of that revision (this repository's own history).
"""
from __future__ import annotations

import argparse
import gzip
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "tests" / "generation" / "data" / "reach_decisions.json.gz"


def spread(records: list[dict], count: int) -> list[dict]:
    """``count`` layouts spread over the fixture (every rejected one among them when there is room)."""
    if count >= len(records):
        return records
    step = len(records) / count
    return [records[int(k * step)] for k in range(count)]


def time_check(count: int) -> dict:
    """Time the importable ``ReachCheck`` on ``count`` fixture layouts (one more first, untimed: caches)."""
    from muble import get_registry
    from muble.core.scene_io import scene_from_dict
    from muble.generation.reachability import ReachCheck
    from muble.sim.build import object_models

    with gzip.open(FIXTURE, "rt") as f:
        records = spread(json.load(f)["layouts"], count)
    objects = get_registry().create("object_set", "shopvrb2")
    check = ReachCheck(None, "approach")
    inputs = []
    for record in records:
        scene = scene_from_dict(record["scene"])
        inputs.append((scene, object_models(scene, objects)))
    check(*inputs[-1])
    seconds, cpu, decisions = [], [], []
    for scene, models in inputs:
        t, c = time.perf_counter(), time.process_time()
        decisions.append(check(scene, models))
        seconds.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    same = sum(d == r["decision"] for d, r in zip(decisions, records))
    return {"s_per_layout": sum(seconds) / len(seconds), "cpu_s_per_layout": sum(cpu) / len(cpu),
            "median_s": sorted(seconds)[len(seconds) // 2], "max_s": max(seconds), "layouts": len(records),
            "decided_as_recorded": same}


def baseline(rev: str, count: int) -> dict:
    with tempfile.TemporaryDirectory() as tree:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev], check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", tree], input=archive, check=True)
        env = {**os.environ, "PYTHONPATH": tree}
        out = subprocess.run([sys.executable, __file__, "--worker", "--layouts", str(count)], cwd=tree, env=env,
                             check=True, capture_output=True, text=True, timeout=3600).stdout
    return json.loads(out.strip().splitlines()[-1])


def _entry_points_of_this_tree() -> None:
    """In the baseline's tree, leave out the installed entry points whose modules that tree lacks (plugins added
    since, e.g. the learned agents): their hooks are unknown to its plugin manager."""
    from muble.plugins import manager

    tree, listed = Path.cwd(), manager._entry_points

    def present(ep) -> bool:
        module = Path(*ep.value.split(":")[0].split("."))
        return (tree / module).with_suffix(".py").is_file() or (tree / module / "__init__.py").is_file()

    manager._entry_points = lambda: [ep for ep in listed() if present(ep)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layouts", type=int, default=40, help="fixture layouts timed (all: 312)")
    parser.add_argument("--baseline-rev", default="59a4fc7", help="revision whose check is the baseline")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        _entry_points_of_this_tree()
        print(json.dumps(time_check(args.layouts)))
        return
    now = time_check(args.layouts)
    before = baseline(args.baseline_rev, args.layouts)
    print(json.dumps({
        "benchmark": "reach_check", "metric": "reach check, seconds per candidate layout", "unit": "s",
        "value": round(now["s_per_layout"], 3), "goal": 0.3,
        "baseline_s": round(before["s_per_layout"], 3), "speedup": round(before["s_per_layout"] / now["s_per_layout"], 2),
        "cpu_s": round(now["cpu_s_per_layout"], 3), "baseline_cpu_s": round(before["cpu_s_per_layout"], 3),
        "now": now, "baseline": {**before, "rev": args.baseline_rev},
    }))


if __name__ == "__main__":
    main()
