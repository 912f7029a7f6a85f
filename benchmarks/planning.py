"""Planning time per move and success rate of the OMPL planner on seeded tabletop scenes (Panda).

Each scene has three to five random boxes on the table; each query is a random top-down hand pose above the
table, planned from where the previous move ended. A query is feasible when a collision-free IK solution
exists for its goal; only feasible queries count towards the success rate. Baseline, in the same run: the
same queries with plain RRTConnect (no direct-segment shortcut).

Run from the repository root: ``python benchmarks/planning.py [--scenes 10] [--queries 10]``.
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests.support: helpers shared with the tests

from muble import JointGoal, PlanningError, Pose, PoseGoal  # noqa: E402
from muble_plugins.planners.ompl_planner import OmplPlanner  # noqa: E402
from muble.core import streams  # noqa: E402
from tests.support.tabletop import build_tabletop  # noqa: E402

# Seeded as before named streams (muble.core.streams.legacy_stream): the figures docs/ reports were measured so.
SCENES = streams.declare_legacy("bench.planning.scenes", "the boxes of every scene and the pose of every query "
                                "(--seed)")


def random_boxes(rng: np.random.Generator, table_z: float) -> list:
    boxes = []
    for _ in range(rng.integers(3, 6)):
        half = rng.uniform([0.02, 0.02, 0.03], [0.06, 0.06, 0.12])
        centre = (rng.uniform(-0.25, 0.3), rng.uniform(-0.3, 0.3), table_z + half[2])
        boxes.append((tuple(centre), tuple(half)))
    return boxes


def run(scenes: int, queries: int, seed: int) -> dict:
    rng = streams.legacy_stream(SCENES, seed)
    timings = {"ompl": [], "baseline": []}
    solved = {"ompl": 0, "baseline": 0}
    feasible = infeasible = 0
    planners = {"ompl": OmplPlanner(), "baseline": OmplPlanner(try_direct=False)}
    for _ in range(scenes):
        while True:  # boxes that leave the arm's home pose free
            scene = build_tabletop("Panda", boxes=random_boxes(rng, 0.8))
            world = scene.collision_world()
            if world.is_valid(scene.home_q):
                break
        down = world.ee_pose(scene.home_q).quat
        start = scene.home_q
        for _ in range(queries):
            target = np.array([rng.uniform(-0.25, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(0.9, 1.1)])
            goal = PoseGoal(Pose(target, down))
            try:
                goal_q = world.inverse_kinematics(goal, seeds=start[None])
            except PlanningError:
                infeasible += 1
                continue
            feasible += 1
            for name, planner in planners.items():
                began = time.perf_counter()
                try:
                    # Pose goal: the timing includes IK, as a primitive's move does.
                    planner.plan(start, goal if name == "ompl" else JointGoal(goal_q), world)
                    solved[name] += 1
                except PlanningError as e:
                    logging.getLogger("planning").warning("%s failed: %s", name, e)
                timings[name].append(time.perf_counter() - began)
            start = goal_q
    ms = {k: np.array(v) * 1e3 for k, v in timings.items()}
    return {
        "benchmark": "planning",
        "metric": "median planning time per move (OMPL, pose goal incl. IK)",
        "value": round(float(np.median(ms["ompl"])), 2),
        "unit": "ms",
        "goal": 50,
        "p95_ms": round(float(np.percentile(ms["ompl"], 95)), 2),
        "success_rate": round(solved["ompl"] / max(feasible, 1), 4),
        "success_goal": 0.99,
        "feasible_queries": feasible,
        "infeasible_queries": infeasible,
        "baseline_rrtconnect_median_ms": round(float(np.median(ms["baseline"])), 2),
        "baseline_rrtconnect_p95_ms": round(float(np.percentile(ms["baseline"], 95)), 2),
        "baseline_success_rate": round(solved["baseline"] / max(feasible, 1), 4),
        "robot": "Panda",
        "seed": seed,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=20)
    parser.add_argument("--queries", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    print(json.dumps(run(args.scenes, args.queries, args.seed)))


if __name__ == "__main__":
    main()
