"""How far one weighing per object can fail a split, and what deciding its comparisons would cost, by sensor noise.

For each instruction of the split, every weight comparison its program makes (a superlative's chosen object against
each other candidate, an order's neighbours) is a pair of true weights ``gap`` grams apart. A weighing that errs by
a Gaussian of ``sigma`` grams puts the pair in the wrong order with probability ``Phi(-gap / (sigma * sqrt 2))``;
an agent that weighs each object once (the open-loop control) fails the episode unless every pair comes out right.
Printed per ``sigma``: the expected share of episodes that fail so (the control's expected drop), and the readings
per object that the closest pair of each episode needs for its mean difference to be decided at ``z`` standard
errors (the oracle's rule, ``agent.decide_sigmas``), as the median and 90th percentile over the episodes. This is
the Gaussian model of the measured figures of ``benchmarks/weigh_noise.py`` (which weighs in physics), over every
episode of a split.

    python benchmarks/noise_sweep.py --split noisy_sensing --sigmas 9.6 20 30 42 60
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from statistics import NormalDist

WEIGHT_STEPS = ("filter_weight", "order_weight")


def compared_gaps(root: Path, split: str) -> list[list[float]]:
    """Per instruction of the split, the true-weight gaps of every pair its weight steps compare."""
    from muble.io.scene_io import load_scene

    episodes = []
    for path in sorted((root / split / "instructions").glob("*.json")):
        record = json.loads(path.read_text())
        weights = {o.id: o.weight_gt for o in load_scene(root / split / "scenes" / path.name).objects}
        gaps: list[float] = []
        for step in record["program"]:
            ids = step.get("input") or []
            if step["type"] not in WEIGHT_STEPS or len(ids) < 2:
                continue
            ranked = sorted(ids, key=lambda i: weights[i])
            if step["type"] == "filter_weight":
                chosen = ranked[-1] if step["input_value"] == "heaviest" else ranked[0]
                gaps += [abs(weights[chosen] - weights[i]) for i in ranked if i != chosen]
            else:
                gaps += [weights[b] - weights[a] for a, b in zip(ranked, ranked[1:])]
        if gaps:
            episodes.append(gaps)
    return episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--protocol", default="shopvrb2_v2")
    parser.add_argument("--split", default="noisy_sensing")
    parser.add_argument("--sigmas", type=float, nargs="+", default=[9.6, 20.0, 30.0, 42.0, 60.0],
                        help="one weighing's error, sd in grams")
    parser.add_argument("--z", type=float, default=2.5, help="standard errors that decide a comparison")
    args = parser.parse_args()

    from muble.dataset.protocol import load_protocol, shipped_root

    episodes = compared_gaps(shipped_root(load_protocol(args.protocol), args.split), args.split)
    closest = sorted(min(g) for g in episodes)
    phi = NormalDist().cdf
    print(f"{args.protocol} {args.split}: {len(episodes)} episodes that compare weights; closest pair per episode "
          f"{closest[len(closest) // 2]:.1f} g apart at the median, {closest[len(closest) // 10]:.1f} g at the 10th "
          "percentile")
    rows = []
    for sigma in args.sigmas:
        fail = [1.0 - math.prod(1.0 - phi(-g / (sigma * math.sqrt(2.0))) for g in gaps) for gaps in episodes]
        # Readings n of each object so that the mean difference of the closest pair stands z standard errors out:
        # gap >= z * sigma * sqrt(2 / n).
        need = sorted(max(1, math.ceil(2.0 * (args.z * sigma / max(min(g), 1e-9)) ** 2)) for g in episodes)
        row = {"sigma_g": sigma, "one_reading_failure": round(sum(fail) / len(fail), 4),
               "readings_median": need[len(need) // 2], "readings_p90": need[int(0.9 * len(need))]}
        rows.append(row)
        print(f"  sigma {sigma:5.1f} g: one reading each fails {row['one_reading_failure']:.1%} of episodes; "
              f"deciding the closest pair takes {row['readings_median']} readings per object at the median, "
              f"{row['readings_p90']} at the 90th percentile")
    print(json.dumps({"benchmark": "noise_sweep", "split": args.split, "episodes": len(episodes), "rows": rows}))


if __name__ == "__main__":
    main()
