"""``muble compare``: evaluation runs side by side, with intervals and paired tests.

    muble compare outputs/oracle outputs/random [--out compare]

Each RUN is the output folder of a ``muble eval`` run; its ``results.json`` is read and checked. Writes into
``--out``: ``compare.md`` (the runs, the success table with 95% intervals, the chart, the recovery rate after
disturbances of runs that had them, the cost and latency of runs that counted tokens, the paired McNemar tests),
``compare.json`` (the same numbers) and ``compare.png``; the tables are printed. Every run is read and the whole
comparison made before anything is written, and the files reach ``--out`` only when all are written, so a bad run
folder leaves nothing behind.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from muble.core.errors import ConfigError


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="muble compare", description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", metavar="RUN", help="output folder of a `muble eval` run")
    parser.add_argument("--out", default="compare", help="folder for compare.md, compare.json and compare.png "
                                                         "(default: ./compare; created if missing)")
    args = parser.parse_args(argv)
    from muble.evaluation.compare import CHART, chart_groups, compare, labelled, markdown, text
    from muble.evaluation.plot import interval_chart
    from muble.evaluation.results import read_results
    from muble.io.atomic import check_output_folder, staged_folder

    out = check_output_folder(Path(args.out), "--out")
    folders = [Path(r) for r in args.runs]
    if any(f.resolve() == out.resolve() for f in folders):
        raise ConfigError(f"--out {out} is one of the runs; pass another folder for the comparison")
    runs = labelled(folders, [read_results(f) for f in folders])
    comparison = compare(runs)
    files = {"compare.json": json.dumps(comparison, indent=2).encode(),
             "compare.md": markdown(comparison, CHART).encode(),
             CHART: interval_chart(chart_groups(comparison), "success rate per task type (95% intervals)")}
    with staged_folder(out, "--out") as stage:
        for name, data in files.items():
            (stage / name).write_bytes(data)
    print(text(comparison))
    print(f"\nmuble compare: {', '.join(files)} in {out}")
    return 0
