"""The scene generator's reach check: seconds per layout on the recorded candidate layouts of
``tests/generation/data/reach_decisions.json.gz`` (300 generated scenes, the rejected layouts included), against
the check of an earlier revision (default: ``BASELINE_REV``, the check before its last savings) on the same layouts
in the same run, with both decisions compared to the recorded ones.

    python benchmarks/reach_check.py [--layouts 40] [--baseline-rev REV]

The baseline runs in a worker process from ``git archive`` of that revision (this repository's own history). The
two checks take turns layout by layout, so that both are timed under the same load on a shared machine.
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
BASELINE_REV = "32a3307"  # the check before the third round of savings (IK on the robot alone, buffers kept)


def spread(records: list[dict], count: int) -> list[dict]:
    """``count`` layouts spread over the fixture (every rejected one among them when there is room)."""
    if count >= len(records):
        return records
    step = len(records) / count
    return [records[int(k * step)] for k in range(count)]


class Layouts:
    """The importable ``ReachCheck`` over ``count`` fixture layouts, deciding one at a time (one more first,
    untimed: caches)."""

    def __init__(self, count: int):
        from muble import get_registry
        from muble.generation.reachability import ReachCheck
        from muble.io.scene_io import scene_from_dict
        from muble.sim.build import object_models

        with gzip.open(FIXTURE, "rt") as f:
            self.records = spread(json.load(f)["layouts"], count)
        objects = get_registry().create("object_set", "shopvrb2")
        self.check = ReachCheck(None, "approach")
        self.inputs = []
        for record in self.records:
            scene = scene_from_dict(record["scene"])
            self.inputs.append((scene, object_models(scene, objects)))
        self.check(*self.inputs[-1])

    def decide(self, k: int) -> dict:
        """Layout ``k`` decided: seconds, CPU seconds and the decision."""
        t, c = time.perf_counter(), time.process_time()
        decision = self.check(*self.inputs[k])
        return {"s": time.perf_counter() - t, "cpu_s": time.process_time() - c, "decision": decision}


def summary(runs: list[dict]) -> dict:
    seconds, cpu = sorted(r["s"] for r in runs), sorted(r["cpu_s"] for r in runs)
    return {"s_per_layout": sum(seconds) / len(runs), "cpu_s_per_layout": sum(cpu) / len(runs),
            "median_s": seconds[len(runs) // 2], "median_cpu_s": cpu[len(runs) // 2], "max_s": seconds[-1],
            "layouts": len(runs), "decided_as_recorded": sum(r["as_recorded"] for r in runs)}


class Baseline:
    """The check of revision ``rev`` in a worker process over the same layouts, deciding one when asked: timed
    interleaved with this tree's check, so both see the same machine load (the machine is shared)."""

    def __init__(self, rev: str, count: int):
        self.tree = tempfile.TemporaryDirectory()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev], check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", self.tree.name], input=archive, check=True)
        env = {**os.environ, "PYTHONPATH": self.tree.name}
        self.worker = subprocess.Popen([sys.executable, __file__, "--worker", "--layouts", str(count)],
                                       cwd=self.tree.name, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                       text=True)
        self._reply()  # ready

    def _reply(self) -> dict:
        while True:
            line = self.worker.stdout.readline()
            if not line:
                raise RuntimeError(f"the baseline worker ended (exit status {self.worker.wait(timeout=60)})")
            if line.startswith("{"):
                return json.loads(line)

    def decide(self, k: int) -> dict:
        self.worker.stdin.write(f"{k}\n")
        self.worker.stdin.flush()
        return self._reply()

    def close(self) -> None:
        self.worker.stdin.close()
        self.worker.wait(timeout=60)
        self.tree.cleanup()


def _entry_points_of_this_tree() -> None:
    """In the baseline's tree, leave out the installed entry points whose modules that tree lacks (plugins added
    since, e.g. the learned agents): their hooks are unknown to its plugin manager."""
    from muble.plugins import manager

    tree, listed = Path.cwd(), manager._entry_points

    def present(ep) -> bool:
        module = Path(*ep.value.split(":")[0].split("."))
        return (tree / module).with_suffix(".py").is_file() or (tree / module / "__init__.py").is_file()

    manager._entry_points = lambda: [ep for ep in listed() if present(ep)]


def worker(count: int) -> None:
    """Decide the layouts whose indices arrive on stdin, one JSON line each on stdout."""
    _entry_points_of_this_tree()
    layouts = Layouts(count)
    print(json.dumps({"ready": len(layouts.records)}), flush=True)
    for line in sys.stdin:
        print(json.dumps(layouts.decide(int(line))), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layouts", type=int, default=40, help="fixture layouts timed (all: 312)")
    parser.add_argument("--baseline-rev", default=BASELINE_REV, help="revision whose check is the baseline")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args.layouts)
        return
    before = Baseline(args.baseline_rev, args.layouts)
    layouts = Layouts(args.layouts)
    now_runs, before_runs = [], []
    try:
        for k in range(len(layouts.records)):  # each layout by both checks, which one first alternating
            if k % 2:
                before_runs.append(before.decide(k))
                now_runs.append(layouts.decide(k))
            else:
                now_runs.append(layouts.decide(k))
                before_runs.append(before.decide(k))
    finally:
        before.close()
    # Compared here, with this tree's rule (the baseline's tree may predate it): word for word, the measured numbers
    # aside.
    from muble.generation.reachability import same_decision

    for runs in (now_runs, before_runs):
        for k, run in enumerate(runs):
            run["as_recorded"] = same_decision(run.pop("decision"), layouts.records[k]["decision"])
    now, base = summary(now_runs), summary(before_runs)
    print(json.dumps({
        "benchmark": "reach_check", "metric": "reach check, seconds per candidate layout", "unit": "s",
        "value": round(now["s_per_layout"], 3), "goal": 0.3,
        "baseline_s": round(base["s_per_layout"], 3), "speedup": round(base["s_per_layout"] / now["s_per_layout"], 2),
        "median_s": round(now["median_s"], 3), "baseline_median_s": round(base["median_s"], 3),
        "cpu_s": round(now["cpu_s_per_layout"], 3), "baseline_cpu_s": round(base["cpu_s_per_layout"], 3),
        "median_cpu_s": round(now["median_cpu_s"], 3), "baseline_median_cpu_s": round(base["median_cpu_s"], 3),
        "load_average": os.getloadavg()[0], "now": now, "baseline": {**base, "rev": args.baseline_rev},
    }))


if __name__ == "__main__":
    main()
