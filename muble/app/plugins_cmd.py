"""``muble plugins``: every registered plugin by kind, with the package that provides it (primitives with their
parameters: ``--kind primitive``, or ``--json``), then the installed plugin packages left out as broken, each with
its error and how to fix or uninstall it."""
from __future__ import annotations

import argparse
import dataclasses
import json
from typing import Any

from muble.core.params import specs
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
        # A broken package registered nothing, so it has no kind: listed only when no kind is asked for.
        broken = [] if args.kind else [{"kind": "broken", "name": b.name, "plugin": b.name,
                                        "distribution": b.distribution, "description": f"left out: {b.error}",
                                        "error": b.error, "fix": b.fix} for b in registry.broken]
        print(json.dumps([{"kind": p.kind, "name": p.record.name, "plugin": p.plugin,
                           "distribution": p.distribution, "description": p.record.description,
                           **primitive_facts(p)} for p in rows] + broken, indent=2))
        return 0
    widths = [max([len(h)] + [len(c) for c in col]) for h, col in zip(
        ("KIND", "NAME", "PACKAGE"),
        ([p.kind for p in rows], [p.record.name for p in rows], [f"{p.distribution}:{p.plugin}" for p in rows]),
    )]
    print(f"{'KIND':<{widths[0]}}  {'NAME':<{widths[1]}}  {'PACKAGE':<{widths[2]}}  DESCRIPTION")
    for p in rows:
        print(f"{p.kind:<{widths[0]}}  {p.record.name:<{widths[1]}}  {p.distribution + ':' + p.plugin:<{widths[2]}}  "
              f"{p.record.description}")
        if p.kind == "primitive" and args.kind == "primitive":  # the parameters, when primitives are asked for
            indent = " " * (widths[0] + widths[1] + 6)
            for param in specs(getattr(p.record.factory, "params", ())):
                print(f"{indent}{param.describe()}" + (f": {param.doc}" if param.doc else ""))
    if registry.broken:
        print("\nBROKEN (installed, left out: every command runs without them)")
        for b in registry.broken:
            print(f"{b.distribution}:{b.name} ({b.target})  {b.failure}\n    fix: {b.fix}")
    return 0


def primitive_facts(p: Any) -> dict[str, Any]:
    """For a primitive: ``params`` (each declared parameter: name, kind, required, low, high, length, default,
    doc; docs/agent_api.md), ``measures`` and ``measure_unit`` (what its reading is); empty for other kinds."""
    if p.kind != "primitive":
        return {}
    factory = p.record.factory
    return {"params": [dataclasses.asdict(param) for param in specs(getattr(factory, "params", ()))],
            "measures": getattr(factory, "measures", None), "measure_unit": getattr(factory, "measure_unit", "")}
