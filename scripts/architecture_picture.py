"""Draw the package picture of docs/architecture.md from the code: one box per package, one arrow per import.

Every ``import`` of ``muble/`` and ``muble_plugins/`` (those inside functions too, not those under
``if TYPE_CHECKING:``) is read with ``ast``. A package is ``muble.X`` or ``muble_plugins.X`` (a module directly under
``muble/`` counts as the package ``muble``). An arrow A -> B says that some module of A imports some module of B.
Packages stand in rows: a package sits one row above the highest package it imports, so every arrow points down,
and a circle (which the layering test forbids) would show as an arrow pointing up, drawn in red.

    python scripts/architecture_picture.py                  # writes docs/images/architecture.svg
    python scripts/architecture_picture.py --check          # exit 1 if the file differs from the code's picture

The SVG is plain text and deterministic (sorted names, fixed layout), so ``--check`` compares bytes;
``tests/core/test_core_layering.py`` runs it.
"""
from __future__ import annotations

import argparse
import ast
import sys
from html import escape
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "images" / "architecture.svg"
ROOTS = ("muble", "muble_plugins")

BOX_W, BOX_H, GAP_X, GAP_Y, MARGIN = 172, 40, 16, 70, 20


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def package_of(module: str) -> str | None:
    """``muble.core.scene`` -> ``muble.core``; ``muble.cli`` -> ``muble``; anything outside the two roots -> None."""
    parts = module.split(".")
    if parts[0] not in ROOTS:
        return None
    if len(parts) == 1:
        return parts[0]
    top = ROOT.joinpath(*parts[:2])
    return ".".join(parts[:2]) if top.is_dir() else parts[0]


def _runtime(node: ast.AST):
    for child in ast.iter_child_nodes(node):
        test = child.test if isinstance(child, ast.If) else None
        if (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or \
                (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"):
            for c in child.orelse:
                yield c
                yield from _runtime(c)
            continue
        yield child
        yield from _runtime(child)


def imported_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    this = module_name(path)
    package = this if path.name == "__init__.py" else this.rpartition(".")[0]
    found = set()
    for node in _runtime(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                found.add(".".join(base + ([node.module] if node.module else [])))
            elif node.module:
                found.add(node.module)
    return found


def graph() -> tuple[dict[str, int], set[tuple[str, str]]]:
    """Packages with their module counts, and the import arrows between packages."""
    counts: dict[str, int] = {}
    edges: set[tuple[str, str]] = set()
    for root in ROOTS:
        for path in sorted((ROOT / root).rglob("*.py")):
            if "build" in path.relative_to(ROOT).parts:
                continue
            source = package_of(module_name(path))
            counts[source] = counts.get(source, 0) + 1
            for imported in imported_modules(path):
                target = package_of(imported)
                if target is not None and target != source:
                    edges.add((source, target))
    return counts, edges


def rows(packages: list[str], edges: set[tuple[str, str]]) -> dict[str, int]:
    """Row 0 imports nothing; a package's row is one above the highest row it imports (a circle is cut)."""
    out: dict[str, int] = {}

    def row(p: str, visiting: frozenset[str]) -> int:
        if p in out:
            return out[p]
        below = [row(t, visiting | {p}) for s, t in sorted(edges) if s == p and t not in visiting | {p}]
        out[p] = 1 + max(below) if below else 0
        return out[p]

    for p in packages:
        row(p, frozenset())
    return out


def svg(counts: dict[str, int], edges: set[tuple[str, str]]) -> str:
    packages = sorted(counts)
    level = rows(packages, edges)
    top = max(level.values())
    by_row = {r: sorted(p for p in packages if level[p] == r) for r in range(top + 1)}
    widest = max(len(v) for v in by_row.values())
    width = 2 * MARGIN + widest * BOX_W + (widest - 1) * GAP_X
    height = 2 * MARGIN + (top + 1) * BOX_H + top * GAP_Y
    place = {}
    for r, names in by_row.items():
        span = len(names) * BOX_W + (len(names) - 1) * GAP_X
        x0 = (width - span) / 2
        y = MARGIN + (top - r) * (BOX_H + GAP_Y)
        for i, name in enumerate(names):
            place[name] = (x0 + i * (BOX_W + GAP_X), y)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height:.0f}" '
           f'viewBox="0 0 {width:.0f} {height:.0f}" font-family="sans-serif" font-size="12">',
           '<defs><marker id="a" viewBox="0 0 10 10" refX="10" refY="5" markerWidth="6" markerHeight="6" '
           'orient="auto-start-reverse"><path d="M 0 0 L 10 5 L 0 10 z" fill="#555"/></marker></defs>',
           f'<rect width="{width:.0f}" height="{height:.0f}" fill="white"/>']
    for source, target in sorted(edges):
        (sx, sy), (tx, ty) = place[source], place[target]
        up = level[target] >= level[source]
        colour = "#c00" if up else "#999"
        x1, y1 = sx + BOX_W / 2, sy + (0 if up else BOX_H)
        x2, y2 = tx + BOX_W / 2, ty + (BOX_H if up else 0)
        out.append(f'<line x1="{x1:.1f}" y1="{y1:.1f}" x2="{x2:.1f}" y2="{y2:.1f}" stroke="{colour}" '
                   f'stroke-width="0.8" marker-end="url(#a)"><title>{escape(source)} imports {escape(target)}'
                   f'</title></line>')
    for name in packages:
        x, y = place[name]
        fill = "#e8f0fb" if name.startswith("muble_plugins") else "#f4f4f4"
        out.append(f'<rect x="{x:.1f}" y="{y:.1f}" width="{BOX_W}" height="{BOX_H}" rx="5" fill="{fill}" '
                   f'stroke="#333"/>')
        out.append(f'<text x="{x + BOX_W / 2:.1f}" y="{y + 17:.1f}" text-anchor="middle">{escape(name)}</text>')
        modules = counts[name]
        out.append(f'<text x="{x + BOX_W / 2:.1f}" y="{y + 32:.1f}" text-anchor="middle" font-size="10" '
                   f'fill="#555">{modules} module{"s" if modules != 1 else ""}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare with the file instead of writing it")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    picture = svg(*graph())
    if args.check:
        if not args.out.is_file() or args.out.read_text() != picture:
            print(f"{args.out} is not the code's picture: run python scripts/architecture_picture.py",
                  file=sys.stderr)
            return 1
        return 0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(picture)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
