"""The reference of MuBlE's public API, generated from the docstrings with pdoc (``pip install "muble[docs]"``).

    python scripts/api_reference.py            # HTML into docs/api/ (not kept in git: it is made from the code)
    python scripts/api_reference.py --out DIR

The public API is what plugins and agents use: the modules the plugin guide lists as the public API
(docs/plugins.md, "The public API"; a test keeps ``API_MODULES`` holding every one of them) and the action loop's
modules an agent's author reads. The test suite builds it too and fails on a public name without a docstring, so
the reference cannot fall behind the code.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

# The modules of docs/plugins.md's public API, then those of the action loop, then the built-in plugins' public
# functions.
API_MODULES = ("muble", "muble.plugins", "muble.core.interfaces", "muble.core.environment", "muble.core.types",
               "muble.core.errors", "muble.core.scene", "muble.core.objects", "muble.core.params", "muble.core.ranges",
               "muble.core.symbolic", "muble.core.observation", "muble.core.object_physics",
               "muble.core.physical_properties", "muble.core.streams", "muble.core.training", "muble.programs.program",
               "muble.programs.descriptions", "muble.stage.table", "muble.stage.rest", "muble.stage.footprint",
               "muble.io.scene_io", "muble.io.instructions_io", "muble.episode", "muble.episode.loop",
               "muble.episode.modes", "muble_plugins.tasks")


def undocumented(modules: tuple[str, ...] = API_MODULES) -> list[str]:
    """Public names of ``modules`` (their ``__all__``, else every name not starting with ``_``) without a
    docstring."""
    import pdoc.doc

    missing = []
    for name in modules:
        module = pdoc.doc.Module.from_name(name)
        if not module.docstring.strip():
            missing.append(name)
        for member in module.members.values():
            if member.name.startswith("_") and member.name != "__version__":
                continue
            if isinstance(member, pdoc.doc.Variable) and (member.taken_from[0] != name or member.name == "log"):
                continue  # a variable is documented where it is defined (pdoc reads no re-export's docstring)
            if isinstance(member, pdoc.doc.Variable) and member.name.isupper() and name != "muble.core.types":
                continue  # module constants are documented by the comment block above them
            if not member.docstring.strip():
                missing.append(f"{name}.{member.name}")
    return missing


def build(out: Path, modules: tuple[str, ...] = API_MODULES) -> Path:
    """Write the HTML reference of ``modules`` into ``out``; returns its index page."""
    import pdoc

    pdoc.render.configure(docformat="restructuredtext", show_source=False,
                          footer_text="MuBlE public API, generated from the docstrings")
    pdoc.pdoc(*modules, output_directory=out)
    return out / "index.html"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "api")
    args = parser.parse_args(argv)
    try:
        import pdoc  # noqa: F401
    except ImportError:
        print("api_reference: needs pdoc: pip install 'muble[docs]'", file=sys.stderr)
        return 2
    index = build(args.out)
    missing = undocumented()
    for name in missing:
        print(f"api_reference: no docstring: {name}", file=sys.stderr)
    print(f"API reference: {index}")
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
