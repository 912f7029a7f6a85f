"""The results table of docs/learned.md: success per task type with 95% Wilson intervals, one row per
`muble eval` run, and the paper's figures (Nazarczuk et al. 2025, CLIER) beside them.

    python scripts/results_table.py "random=runs/random_test" "learned planner (program + graph)=runs/planner_test" \
        ... --out table.md

Each argument is LABEL=FOLDER, the output folder of a `muble eval` run (its results.json). The row also names the
run's protocol split, track and observation mode, so rows run under other settings are not mistaken for each other.
`--paper ycb` puts the paper's figures for its 30 YCB scenes beside the runs instead of its SHOP-VRB2 ones.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from muble.core.errors import ConfigError
from muble.evaluation.results import read_results
from muble.evaluation.stats import wilson
from muble.io.instructions_io import SHOPVRB2_TEMPLATES

TEMPLATES = list(SHOPVRB2_TEMPLATES)
# The paper's SHOP-VRB2 simulation figures (perception included): 100% on the single-object tasks, 33% on
# stacking by weight, 43.9% overall. It reports no other task type separately.
PAPER = {"measure_weight_single": "100%", "move_single": "100%", "stack_weight": "33%", "overall": "43.9%"}
# Its YCB figures: 76.7% of the 30 scenes in simulation with its perception (64.4% on the real robot, 86.7% with
# ground-truth poses and attributes); no task type separately.
PAPERS = {"shopvrb2": ("CLIER, simulation, perception included", PAPER),
          "ycb": ("CLIER, YCB scenes, simulation, perception included", {"overall": "76.7%"})}


def cell(successes: int, n: int) -> str:
    if n == 0:
        return "—"
    low, high = wilson(successes, n)
    return f"{100 * successes / n:.1f}% [{100 * low:.0f}–{100 * high:.0f}] ({successes}/{n})"


def counts(folder: Path) -> tuple[dict[str, list[int]], str]:
    """Successes and episodes per template of a run, and what it ran under (split, track, mode)."""
    results = read_results(folder)
    found: dict[str, list[int]] = {}
    for entry in results["splits"].values():
        for episode in entry["episodes"]:
            done = found.setdefault(episode["template"], [0, 0])
            done[0] += episode["outcome"] == "success"
            done[1] += 1
    settings = (f"{results.get('protocol_split') or ','.join(results['splits'])}, {results.get('track')}, "
                f"{results.get('mode')}")
    return found, settings


def table(runs: list[tuple[str, Path]], paper: str = "shopvrb2") -> str:
    """One column per run, one row per task type and one overall; the paper's column last."""
    columns = [(label, *counts(folder)) for label, folder in runs]
    title, figures = PAPERS[paper]
    head = "| task type | " + " | ".join(f"{label} ({settings})" for label, _, settings in columns) \
        + f" | paper ({title}) |"
    lines = [head, "|" + "---|" * (len(columns) + 2)]
    for template in TEMPLATES:
        cells = [cell(*found.get(template, [0, 0])) for _, found, _ in columns]
        lines.append(f"| `{template}` | " + " | ".join(cells) + f" | {figures.get(template, '—')} |")
    overall = [cell(sum(c[0] for c in found.values()), sum(c[1] for c in found.values())) for _, found, _ in columns]
    lines.append("| **overall** | " + " | ".join(overall) + f" | {figures['overall']} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", metavar="LABEL=FOLDER", help="a row's label and its `muble eval` folder")
    parser.add_argument("--out", type=Path, help="write the table here too")
    parser.add_argument("--paper", choices=sorted(PAPERS), default="shopvrb2",
                        help="the paper's figures beside the runs: its SHOP-VRB2 scenes' or its 30 YCB scenes'")
    args = parser.parse_args(argv)
    rows = []
    for item in args.runs:
        label, sep, folder = item.partition("=")
        if not sep or not label or not folder:
            parser.error(f"'{item}' is not LABEL=FOLDER")
        rows.append((label, Path(folder)))
    try:
        text = table(rows, args.paper)
    except ConfigError as e:
        print(f"results_table: error: {e}", file=sys.stderr)
        return 2
    print(text, end="")
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
