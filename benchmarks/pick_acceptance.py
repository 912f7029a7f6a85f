"""Acceptance measurement of the pick primitives on generated SHOP-VRB2 scenes (4-5 objects, natural poses).

For every pickupable object of every scene (objects flagged ``pickupable=False`` — plates, trays, boards, food
boxes — are stationary and skipped, as in SHOP-VRB2): approach + close_gripper + lift, then weigh (relative
error against the ground-truth weight), then lower it straight back down. Counts pick success overall and per
category, the put-downs separately (a pick that succeeded stays a success when the put-down fails), and moves
with unintended contact (arm or held object touching another object, seen in physics).

Run from the repository root:
``python benchmarks/pick_acceptance.py [--scenes 100] [--seed 0] [--robot Panda] [--gripper Robotiq85Gripper]
[--categories mug,glass]``.
"""
from __future__ import annotations

import argparse
import collections
import json
import logging
import time

import numpy as np

from muble import MubleError, get_registry
from muble.generation.generator import SceneGenerator
from muble.sim.build import env_from_object_set
from muble_conf import group_defaults


def act(env, name, **params):
    return get_registry().create("primitive", name, params).execute(env)


def run(scenes: int, seed: int, categories: list[str] | None = None, robot: str = "Panda",
        gripper: str | None = None) -> dict:
    options = {**group_defaults("generator", "shopvrb2"), "object_set": "shopvrb2", "masks": False}
    if categories:
        options["object_set_options"] = {"categories": categories}
    generator = SceneGenerator(options, seed=seed)
    per_category = collections.defaultdict(lambda: [0, 0])
    weight_errors, moves, contact_moves, failures, skipped = [], 0, 0, [], 0
    put_downs, put_down_failures, contact_examples = 0, [], []
    began = time.perf_counter()
    for index in range(scenes):
        scene = generator.generate(index)
        env = env_from_object_set(scene, "shopvrb2", robot={"name": robot, "gripper": gripper or None})
        for obj in scene.objects:
            if not obj.pickupable:
                skipped += 1
                continue
            env.reset()
            ok = False
            try:
                results = []
                for name, params in (("approach", {"target": obj.id}), ("close_gripper", {}), ("lift", {})):
                    results.append(act(env, name, **params))
                    if not results[-1].success:
                        break
                ok = all(r.success for r in results) and env.held_object == obj.id
                for r in results:
                    if "unintended_contacts" in r.info:
                        moves += 1
                        contact_moves += bool(r.info["unintended_contacts"])
                        if r.info["unintended_contacts"]:
                            contact_examples.append((index, obj.name, r.info["unintended_contacts"][:2]))
                if not ok:
                    failures.append((index, obj.id, obj.model, [r.failure_reason for r in results]))
            except MubleError as e:
                failures.append((index, obj.id, obj.model, str(e)[:200]))
            if ok:
                grams = act(env, "weigh").measurement
                weight_errors.append(abs(grams - obj.weight_gt) / obj.weight_gt)
                put_downs += 1
                try:
                    r = act(env, "lower")  # straight back down where it came from
                    moves += 1
                    contact_moves += bool(r.info.get("unintended_contacts"))
                    if not r.success:
                        put_down_failures.append((index, obj.model, r.failure_reason))
                except MubleError as e:
                    put_down_failures.append((index, obj.model, str(e)[:200]))
            per_category[obj.name][0] += ok
            per_category[obj.name][1] += 1
    total_ok = sum(v[0] for v in per_category.values())
    total = sum(v[1] for v in per_category.values())
    log = logging.getLogger("pick")
    for f in failures[:30]:
        log.warning("pick failure: %s", f)
    for f in put_down_failures[:10]:
        log.warning("put-down failure: %s", f)
    for f in contact_examples[:10]:
        log.warning("unintended contact: %s", f)
    return {
        "benchmark": "pick_acceptance",
        "metric": "approach+grasp+lift success rate",
        "value": round(total_ok / max(total, 1), 4),
        "unit": "fraction",
        "goal": 0.98,
        "robot": robot,
        "gripper": gripper or "default",
        "per_category": {k: round(v[0] / v[1], 3) for k, v in sorted(per_category.items())},
        "per_category_counts": {k: f"{v[0]}/{v[1]}" for k, v in sorted(per_category.items())},
        "worst_category_rate": round(min(v[0] / v[1] for v in per_category.values()), 3) if per_category else 0,
        "weigh_max_rel_error": round(float(np.max(weight_errors)), 5) if weight_errors else None,
        "weigh_within_1pct": round(float(np.mean(np.array(weight_errors) < 0.01)), 4) if weight_errors else None,
        "moves": moves,
        "moves_without_unintended_contact": round(1 - contact_moves / max(moves, 1), 4),
        "put_down_success": round(1 - len(put_down_failures) / max(put_downs, 1), 4),
        "picks": total,
        "skipped_not_pickupable": skipped,
        "scenes": scenes,
        "seconds": round(time.perf_counter() - began, 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--robot", default="Panda", help="Panda, Sawyer, UR5e, Kinova3 or IIWA")
    parser.add_argument("--gripper", default="", help="a robosuite gripper instead of the robot's default")
    parser.add_argument("--categories", default="", help="comma-separated categories to sample (default: all)")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    categories = [c.strip() for c in args.categories.split(",") if c.strip()]
    print(json.dumps(run(args.scenes, args.seed, categories or None, args.robot, args.gripper or None)))


if __name__ == "__main__":
    main()
