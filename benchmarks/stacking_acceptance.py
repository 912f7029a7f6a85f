"""Stacking acceptance: for every pair (A, B) the SHOP-VRB2 set can produce, with A stackable and B a stack base,
pick A up (approach + close_gripper + lift), lower it onto B, and check that A rests on B: released, still,
touching B and not the table.

Run from the repository root: ``python benchmarks/stacking_acceptance.py [--robot Panda] [--seed 0]``.
Each pair is one medium-sized model of each category, side by side on the table.
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

from muble import MubleError, get_registry  # noqa: E402
from muble.sim.env import TabletopEnv  # noqa: E402
from muble.core import streams  # noqa: E402
from tests.support.scenes import simple_scene  # noqa: E402

# Seeded as before named streams (muble.core.streams.legacy_stream): the figures docs/ reports were measured so.
OBJECTS = streams.declare_legacy("bench.stacking.objects", "the objects sampled for the categories' flags (0) and for "
                                 "a stacked pair (--seed)")

A_AT, B_AT = (0.42, -0.20), (0.52, 0.12)  # m on the table top, in reach of every supported arm


def act(env, name, **params):
    return get_registry().create("primitive", name, params).execute(env)


def stackable_pairs(objects) -> list[tuple[str, str]]:
    rng = streams.legacy_stream(OBJECTS, 0)
    flags = {c: objects.build(objects.sample(rng, category=c)) for c in objects.categories()}
    return [(a, b) for a in flags if flags[a].stackable for b in flags if flags[b].stack_base]


def rests_on(env, top: int, base: int) -> tuple[bool, str]:
    """True when object ``top`` is out of the hand, still, touching ``base`` and not the table."""
    m, d = env.model, env.data
    a, b = m.body(env.names.objects[top]).id, m.body(env.names.objects[base]).id
    table = m.geom_bodyid[m.geom("table_collision").id]
    touching = set()
    for c in d.contact[: d.ncon]:
        b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
        if a in (b1, b2):
            touching.add(b2 if b1 == a else b1)
    speed = float(np.linalg.norm(d.cvel[a][3:]))
    if env.held_object is not None:
        return False, "still in the hand"
    if speed > 0.01:
        return False, f"moving at {speed:.3f} m/s"
    if b not in touching:
        return False, "not touching the base"
    if table in touching:
        return False, "touching the table"
    return True, ""


def stack_pair(objects, top: str, base: str, robot: str = "Panda", seed: int = 0) -> tuple[bool, str]:
    """Pick a ``top`` object and lower it onto a ``base`` object; (success, reason)."""
    rng = streams.legacy_stream(OBJECTS, seed)
    models = []
    for category in (top, base):
        spec = objects.sample(rng, category=category)
        spec.size, spec.scale = "medium-sized", 1.0
        models.append(objects.build(spec))
    env = TabletopEnv(simple_scene([A_AT, B_AT], models), dict(enumerate(models)), name=robot)
    try:
        for name, params in [("approach", {"target": 0}), ("close_gripper", {}), ("lift", {})]:
            result = act(env, name, **params)
            if not result.success:
                return False, f"{name}: {result.failure_reason}"
        result = act(env, "lower", target=1)
        env.hold(0.5)
        ok, why = rests_on(env, 0, 1)
        if not result.success and ok:
            return False, f"lower: {result.failure_reason}"
        return ok, why
    except MubleError as e:
        return False, str(e)[:200]
    finally:
        env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="Panda")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    objects = get_registry().create("object_set", "shopvrb2")
    began = time.perf_counter()
    results = {}
    for top, base in stackable_pairs(objects):
        ok, why = stack_pair(objects, top, base, args.robot, args.seed)
        results[f"{top} on {base}"] = "ok" if ok else why
        logging.getLogger("stacking").warning("%s on %s: %s", top, base, "ok" if ok else why)
    done = sum(v == "ok" for v in results.values())
    print(json.dumps({
        "benchmark": "stacking_acceptance", "metric": "stackable pairs resting on their base", "robot": args.robot,
        "value": round(done / max(len(results), 1), 4), "unit": "fraction", "goal": 1.0, "pairs": len(results),
        "failures": {k: v for k, v in results.items() if v != "ok"}, "seconds": round(time.perf_counter() - began, 1),
    }))


if __name__ == "__main__":
    main()
