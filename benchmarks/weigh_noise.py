"""Weighing with a noisy wrist sensor: how often one reading puts the closest weights a SHOP-VRB2 template compares
in the wrong order, and how often the oracle's rule (weigh again until the comparison is decided) still does.

The pairs: every weight comparison of the split's instructions (a superlative's object against the runner-up, an
order's neighbours), the closest pair of each step, and of those the closest ``--closest`` fraction (by the
ground-truth gap). Each pair is weighed in physics on its own scene of the frozen split (the stage and robot its
episodes use), with the primitives and the order the oracle uses: move, approach (which tares the empty hand),
close_gripper, lift, weigh, lower; the pair's two objects in turn, ``--readings`` times each, the sensor as
``noise=NAME`` (``muble_conf/noise``) makes it, drawn from the stream of (``--seed``, the episode's index).

Printed: each pair's gap and readings; the readings' errors against the objects' true weights and the time from
tare to reading; the wrong-order rate of one reading (every reading of one object against every reading of the
other, pairs weighted alike) and the rate a Gaussian error of the measured spread predicts; and the oracle's rule
(``muble_plugins.common.books.Certainty``, with ``--reading-noise-g``, ``--decide-sigmas`` and ``--max-readings``)
run on each pair's readings in the order the oracle would take them, from every rotation of each object's readings:
its wrong-order rate and readings per object. The last line is a JSON object.

    python benchmarks/weigh_noise.py                                  # mini, the closest quarter, 5 readings each
    python benchmarks/weigh_noise.py --noise none --readings 1        # the perfect sensor: every order right
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

WEIGHT_STEPS = ("filter_weight", "order_weight")
GOAL, GOAL_RANGE = 0.15, (0.10, 0.20)  # the wrong-order rate of one reading that wrist_ft is calibrated to
OBJECT_SET = "shopvrb2"
PICK = ("move", "approach", "close_gripper", "lift")


def closest_pairs(root: Path, split: str) -> list[dict]:
    """The closest pair of every weight comparison step of the split's instructions, closest first."""
    from muble.io.scene_io import load_scene

    found = []
    for path in sorted((root / split / "instructions").glob("*.json")):
        record = json.loads(path.read_text())
        weights = {o.id: o.weight_gt for o in load_scene(root / split / "scenes" / path.name).objects}
        seen = set()
        for step in record["program"]:
            ids = step.get("input") or []
            if step["type"] not in WEIGHT_STEPS or len(ids) < 2:
                continue
            ranked = sorted(ids, key=lambda i: weights[i])
            if step["type"] == "filter_weight":  # the chosen object against the runner-up
                pair = ranked[-2:] if step["input_value"] == "heaviest" else ranked[:2]
            else:  # the closest neighbours of the order
                pair = min(zip(ranked, ranked[1:]), key=lambda p: weights[p[1]] - weights[p[0]])
            a, b = sorted(pair)
            if (a, b) not in seen:
                seen.add((a, b))
                found.append({"index": record["image_index"], "template": record["template_id"], "file": path.name,
                              "a": a, "b": b, "weights": [weights[a], weights[b]],
                              "gap": abs(weights[a] - weights[b])})
    return sorted(found, key=lambda p: p["gap"])


def weigh_pair(root: Path, split: str, pair: dict, readings: int, noise: dict, seed: int) -> dict:
    """Weigh the pair's objects in turn, ``readings`` times each, as the oracle picks, weighs and puts down."""
    from muble import get_registry
    from muble.io.scene_io import load_scene
    from muble.sim.build import env_from_object_set
    from muble.sim.initial_state import settle_and_check

    registry = get_registry()
    env = env_from_object_set(load_scene(root / split / "scenes" / pair["file"]), OBJECT_SET, visual=False,
                              noise=noise, noise_stream=(seed, pair["index"]))
    settle_and_check(env)
    env.planner = registry.create("planner", "ompl", {})
    tare = env.tare
    tared = [0.0]

    def timed_tare():
        tared[0] = env.data.time
        return tare()

    env.tare = timed_tare
    out = {"readings": {pair["a"]: [], pair["b"]: []}, "tare_to_reading_s": [], "failed": None}
    for _ in range(readings):
        for obj in (pair["a"], pair["b"]):
            for name in PICK:
                params = {} if name == "lift" else {"target": obj}
                result = registry.create("primitive", name, params).execute(env)
                if not result.success:
                    out["failed"] = f"{name}({obj}): {result.failure_reason}"
                    return out
            grams = registry.create("primitive", "weigh", {}).execute(env).measurement
            out["readings"][obj].append(float(grams))
            out["tare_to_reading_s"].append(env.data.time - tared[0])
            lowered = registry.create("primitive", "lower", {}).execute(env)
            if not lowered.success:
                out["failed"] = f"lower({obj}): {lowered.failure_reason}"
                return out
    env.close()
    return out


def rule_on(first: list[float], second: list[float], truth: float, reading_noise_g: float, decide_sigmas: float,
            max_readings: int):
    """The oracle's rule on one pair's readings taken in this order: (wrong order?, readings taken). The less
    certain object is read next; on a tie the one read last (the oracle's hand is still at it)."""
    from muble_plugins.common.books import Certainty

    books = {"weight": {0: [first[0]], 1: [second[0]]}}
    supply = {0: list(first[1:]), 1: list(second[1:])}
    rule = Certainty({"weight": reading_noise_g}, books, decide_sigmas, max_readings)
    last = 1
    while True:
        again = rule.measure_again("weight", [(0, 1)])
        if not again:
            break
        pick = last if last in again else again[0]
        if not supply[pick]:
            break
        books["weight"][pick].append(supply[pick].pop(0))
        last = pick
    means = [math.fsum(books["weight"][k]) / len(books["weight"][k]) for k in (0, 1)]
    return (means[0] - means[1]) * truth <= 0, len(books["weight"][0]) + len(books["weight"][1])


def rule_model(gap: float, sd: float, args, key: int, trials: int = 2000) -> tuple[float, float]:
    """The oracle's rule on Gaussian readings of spread ``sd`` for a pair ``gap`` apart: (wrong-order rate,
    readings per object), over ``trials`` draws from the benchmark's own stream."""
    from muble.core import streams

    purpose = streams.declare("benchmark.weigh_noise", "readings of a pair drawn to model the oracle's rule (pair)")
    rng = streams.stream(purpose, args.seed, key)
    draws = rng.normal(0.0, sd, size=(trials, 2, args.max_readings))
    outcomes = [rule_on(list(gap + d[0]), list(d[1]), gap, args.reading_noise_g, args.decide_sigmas,
                        args.max_readings) for d in draws]
    return float(np.mean([w for w, _ in outcomes])), float(np.mean([n for _, n in outcomes])) / 2


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--protocol", default="shopvrb2_v2")
    parser.add_argument("--split", default="mini")
    parser.add_argument("--closest", type=float, default=0.25, help="fraction of the compared pairs, closest first")
    parser.add_argument("--readings", type=int, default=5, help="weighings of each object of a pair")
    parser.add_argument("--noise", default="wrist_ft", help="muble_conf/noise option")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--reading-noise-g", type=float, default=9.6, help="the oracle's sd of one weighing (g)")
    parser.add_argument("--decide-sigmas", type=float, default=2.5)
    parser.add_argument("--max-readings", type=int, default=None,
                        help="the oracle's bound per object (default: agent.max_readings, at most --readings)")
    args = parser.parse_args()
    if args.max_readings is None:
        from muble_plugins.agents.oracle import OracleConfig

        args.max_readings = min(OracleConfig().max_readings, args.readings)

    from omegaconf import OmegaConf

    from muble.app.config import compose
    from muble.dataset.protocol import load_protocol, shipped_root

    root = shipped_root(load_protocol(args.protocol), args.split)
    noise = OmegaConf.to_container(compose("run", [f"noise={args.noise}"]).noise, resolve=True)
    compared = closest_pairs(root, args.split)
    pairs = compared[:max(1, round(args.closest * len(compared)))]
    print(f"{len(compared)} compared pairs in {args.protocol} {args.split}; the closest {len(pairs)}: gaps "
          f"{pairs[0]['gap']:.1f}-{pairs[-1]['gap']:.1f} g; noise={args.noise} {noise}")
    start = time.perf_counter()
    errors, delays, single, rule_wrong, rule_reads, rows = [], [], [], [], [], []
    for pair in pairs:
        got = weigh_pair(root, args.split, pair, args.readings, noise, args.seed)
        first, second = got["readings"][pair["a"]], got["readings"][pair["b"]]
        truth = pair["weights"][0] - pair["weights"][1]
        errors += [r - pair["weights"][0] for r in first] + [r - pair["weights"][1] for r in second]
        delays += got["tare_to_reading_s"]
        print(f"  {args.split} {pair['index']:>4} {pair['template']:<18} objects {pair['a']},{pair['b']} "
              f"gap {pair['gap']:6.1f} g  readings {np.round(first, 1).tolist()} {np.round(second, 1).tolist()}"
              + (f"  FAILED {got['failed']}" if got["failed"] else ""), flush=True)
        if not first or not second:
            continue
        wrong = [(x - y) * truth <= 0 for x in first for y in second]
        single.append(float(np.mean(wrong)))
        outcomes = [rule_on(first[i:] + first[:i], second[j:] + second[:j], truth, args.reading_noise_g,
                            args.decide_sigmas, args.max_readings)
                    for i in range(len(first)) for j in range(len(second))]
        rule_wrong.append(float(np.mean([w for w, _ in outcomes])))
        rule_reads.append(float(np.mean([n for _, n in outcomes])) / 2)
        rows.append({"index": pair["index"], "template": pair["template"], "gap_g": round(pair["gap"], 2),
                     "single_wrong": round(single[-1], 3), "rule_wrong": round(rule_wrong[-1], 3),
                     "rule_readings_per_object": round(rule_reads[-1], 2), "failed": got["failed"]})
    errors = np.array(errors)
    sd = float(errors.std(ddof=1)) if len(errors) > 1 else 0.0
    gaps = [p["gap"] for p in pairs]
    model = float(np.mean([0.5 * math.erfc(g / (sd * 2.0) if sd > 0 else math.inf) for g in gaps]))
    modelled = [rule_model(g, sd, args, k) for k, g in enumerate(gaps)] if sd > 0 else [(0.0, 1.0)]
    rule_model_wrong, rule_model_reads = (float(np.mean(v)) for v in zip(*modelled))
    print(f"reading errors (g): mean {errors.mean():+.2f}, sd {sd:.2f}, 5/50/95th percentiles "
          f"{np.percentile(errors, [5, 50, 95]).round(2).tolist()}, worst {np.abs(errors).max():.2f} "
          f"({len(errors)} readings); tare to reading {np.mean(delays):.2f} s (min {np.min(delays):.2f}, max "
          f"{np.max(delays):.2f})")
    print(f"one reading: {np.mean(single):.3f} of the closest pairs in the wrong order (a Gaussian error of sd "
          f"{sd:.2f} g predicts {model:.3f}); the oracle's rule (sd {args.reading_noise_g} g, "
          f"{args.decide_sigmas} standard errors, at most {args.max_readings} readings): {np.mean(rule_wrong):.3f}, "
          f"{np.mean(rule_reads):.2f} readings per object (Gaussian readings of sd {sd:.2f} g predict "
          f"{rule_model_wrong:.3f}, {rule_model_reads:.2f} readings per object)")
    print(json.dumps({
        "benchmark": "weigh_noise", "metric": "wrong-order rate of one weighing on the closest compared pairs",
        "value": round(float(np.mean(single)), 4), "unit": "ratio", "goal": GOAL, "goal_range": GOAL_RANGE,
        "noise": args.noise,
        "split": f"{args.protocol}.{args.split}", "pairs": len(single), "compared_pairs": len(compared),
        "gap_range_g": [round(min(gaps), 2), round(max(gaps), 2)], "readings_per_object": args.readings,
        "reading_error_g": {"mean": round(float(errors.mean()), 3), "sd": round(sd, 3),
                            "p5": round(float(np.percentile(errors, 5)), 3),
                            "p95": round(float(np.percentile(errors, 95)), 3),
                            "worst": round(float(np.abs(errors).max()), 3)},
        "tare_to_reading_s": round(float(np.mean(delays)), 3), "model_wrong_rate": round(model, 4),
        "oracle_rule": {"reading_noise_g": args.reading_noise_g, "decide_sigmas": args.decide_sigmas,
                        "max_readings": args.max_readings,
                        "wrong_rate": round(float(np.mean(rule_wrong)), 4),
                        "readings_per_object": round(float(np.mean(rule_reads)), 3),
                        "model_wrong_rate": round(rule_model_wrong, 4),
                        "model_readings_per_object": round(rule_model_reads, 3)},
        "per_pair": rows, "seconds": round(time.perf_counter() - start, 1)}))


if __name__ == "__main__":
    main()
