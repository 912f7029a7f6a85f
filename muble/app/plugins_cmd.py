"""``muble plugins``: every registered plugin by kind, with the package that provides it."""
from __future__ import annotations

import argparse
import json

from muble.plugins.records import KINDS
from muble.plugins.registry import get_registry


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="muble plugins", description=__doc__)
    parser.add_argument("--kind", choices=sorted(KINDS), help="list only this kind")
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    args = parser.parse_args(argv)
    registry = get_registry()
    rows = [p for p in registry.all() if args.kind in (None, p.kind)]
    if args.json:
        print(json.dumps([{"kind": p.kind, "name": p.record.name, "plugin": p.plugin,
                           "distribution": p.distribution, "description": p.record.description} for p in rows],
                         indent=2))
        return 0
    widths = [max([len(h)] + [len(c) for c in col]) for h, col in zip(
        ("KIND", "NAME", "PACKAGE"),
        ([p.kind for p in rows], [p.record.name for p in rows], [f"{p.distribution}:{p.plugin}" for p in rows]),
    )]
    print(f"{'KIND':<{widths[0]}}  {'NAME':<{widths[1]}}  {'PACKAGE':<{widths[2]}}  DESCRIPTION")
    for p in rows:
        print(f"{p.kind:<{widths[0]}}  {p.record.name:<{widths[1]}}  {p.distribution + ':' + p.plugin:<{widths[2]}}  "
              f"{p.record.description}")
    return 0
