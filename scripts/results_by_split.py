"""The results table of docs/results.md: one row per contestant, one column per protocol split, every cell the
run's successes over its episodes with the Wilson 95% interval, and under the table each row's command and its
failures by class with the three most common causes.

    python scripts/results_by_split.py \\
        --row "oracle (privileged)|muble eval protocol=shopvrb2_v2 benchmark.split=SPLIT agent=oracle|runs/oracle_{split}" \\
        --row "random|...|runs/random_{split}" --out table.md

Each ``--row`` is ``LABEL|COMMAND|FOLDER`` with ``{split}`` in FOLDER (and ``SPLIT`` in COMMAND) standing for the
split: the folder is a ``muble eval`` output (its ``results.json`` and ``episodes_<split>.jsonl``). A split with
no folder is a cell that says "not measured". The first column is ``test``, or ``mini`` where a row has no
``test`` run (the cell says which). A run with fewer episodes than its split holds (``evaluation.limit``) says
"first N".
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from muble.dataset.protocol import load_protocol, split_spec
from muble.evaluation.site import failure_taxonomy

GENERALISATION = ["unseen_objects", "unseen_properties", "perturbed_views", "long_horizon"]


def _read(folder: Path, split: str) -> tuple[dict, list[dict]] | None:
    results = folder / "results.json"
    if not results.is_file():
        return None
    data = json.loads(results.read_text())
    if split not in data.get("splits", {}):
        return None
    records = [json.loads(line) for line in (folder / f"episodes_{split}.jsonl").read_text().splitlines() if line]
    return data, records


def cell(folder: Path, split: str, prefix: str = "") -> str:
    found = _read(folder, split)
    if found is None:
        return "not measured"
    data, _ = found
    overall = data["splits"][split]["summary"]["overall"]
    low, high = overall["ci"]
    size = split_spec(load_protocol(data["protocol"]), split).get("size") if data.get("protocol") else None
    limited = f", first {overall['episodes']}" if size and overall["episodes"] < size else ""
    return (f"{prefix}{overall['successes']:,}/{overall['episodes']:,} [{100 * low:.1f}%, {100 * high:.1f}%]"
            f"{limited}")


def table(rows: list[tuple[str, str, str]]) -> str:
    lines = ["| contestant | `test` (or `mini`) | " + " | ".join(f"`{s}`" for s in GENERALISATION) + " |",
             "|---|---|" + "---|" * len(GENERALISATION)]
    notes = []
    for i, (label, command, pattern) in enumerate(rows, 1):
        test = Path(pattern.format(split="test"))
        first = cell(test, "test") if _read(test, "test") else cell(Path(pattern.format(split="mini")), "mini",
                                                                      "mini: ")
        cells = [first] + [cell(Path(pattern.format(split=s)), s) for s in GENERALISATION]
        lines.append(f"| {label} [{i}] | " + " | ".join(cells) + " |")
        records = []
        for split in ["test", "mini", *GENERALISATION]:
            found = _read(Path(pattern.format(split=split)), split)
            records += found[1] if found else []
        taxonomy = failure_taxonomy(records)
        note = [f"[{i}] **{label}**: `{command}`"]
        for outcome, causes in sorted(taxonomy.items(), key=lambda kv: -sum(kv[1].values())):
            top = "; ".join(f"{cause} ({n})" for cause, n in causes.most_common(3))
            note.append(f"  - `{outcome}` {sum(causes.values())}: {top}")
        if not taxonomy and records:
            note.append("  - no failure")
        notes.append("\n".join(note))
    return "\n".join(lines) + "\n\n" + "\n".join(notes) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--row", action="append", required=True, help="LABEL|COMMAND|FOLDER with {split}")
    parser.add_argument("--out", type=Path, help="write the table here (else print it)")
    args = parser.parse_args(argv)
    rows = []
    for row in args.row:
        parts = row.split("|")
        if len(parts) != 3 or "{split}" not in parts[2]:
            parser.error(f"--row {row!r}: give LABEL|COMMAND|FOLDER, the folder with {{split}} in it")
        rows.append((parts[0], parts[1], parts[2]))
    text = table(rows)
    if args.out:
        args.out.write_text(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
