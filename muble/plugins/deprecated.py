"""Deprecated aliases: the modules of the public API that moved, importable under their old names for one minor
release.

When ``muble/core`` was split by concern, its file, program and tabletop modules moved to ``muble.io``,
``muble.programs`` and ``muble.stage``. A package written against the earlier documentation
(``from muble.core.program import execute``) still imports: the old name is the moved module itself (the same
module object, so its classes and functions are the very same), and the import warns once with a
``MubleDeprecationWarning`` that names the new module. The aliases go in ``REMOVED_IN``; a test fails when the
version reaches it with the aliases still here.

No file stands at an old place (``muble/core`` holds the data model and the interfaces only): ``install()`` puts
a finder at the end of ``sys.meta_path`` that answers for the names of ``MOVED`` only, after every real module
has had its chance. ``import muble`` installs it.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from pathlib import Path
from types import ModuleType

from muble.core.errors import MubleDeprecationWarning

# The MuBlE version that drops the aliases (the one after the release that moved the modules).
REMOVED_IN = "0.2"

# Old module -> where it is now (moved by the core split; docs/plugins.md, "The public API").
MOVED: dict[str, str] = {
    "muble.core.descriptions": "muble.programs.descriptions",
    "muble.core.program": "muble.programs.program",
    "muble.core.scene_io": "muble.io.scene_io",
    "muble.core.instructions_io": "muble.io.instructions_io",
    "muble.core.layout": "muble.io.layout",
    "muble.core.manifest": "muble.io.manifest",
    "muble.core.keyframe_states": "muble.io.keyframe_states",
    "muble.core.action_names": "muble.io.action_names",
    "muble.core.atomic": "muble.io.atomic",
    "muble.core.image_grid": "muble.io.image_grid",
    "muble.core.table": "muble.stage.table",
    "muble.core.rest": "muble.stage.rest",
    "muble.core.free_place": "muble.stage.free_place",
    "muble.core.footprint": "muble.stage.footprint",
    "muble.core.geometry": "muble.stage.geometry",
    "muble.core.camera": "muble.stage.camera",
    "muble.core.quiet": "muble.quiet",
}

# Frames of the import machinery and of this module, skipped so that the warning points at the import statement.
_SKIPPED = ("<frozen importlib", str(Path(__file__)))


def message(old: str) -> str:
    """What the warning for importing ``old`` says."""
    return (f"{old} moved to {MOVED[old]}: import {MOVED[old]} instead (the old name is deprecated and goes in "
            f"MuBlE {REMOVED_IN})")


class _Alias(importlib.abc.Loader):
    """Loads an old name as the module it moved to: ``exec_module`` puts that module in ``sys.modules`` under the
    old name, and the import system hands out what ``sys.modules`` holds once the loader is done."""

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> None:
        return None  # a placeholder, replaced in exec_module

    def exec_module(self, module: ModuleType) -> None:
        old = module.__name__
        moved = importlib.import_module(MOVED[old])
        warnings.warn(message(old), MubleDeprecationWarning, stacklevel=2, skip_file_prefixes=_SKIPPED)
        sys.modules[old] = moved


class _Finder(importlib.abc.MetaPathFinder):
    """Finds the old names of ``MOVED`` (and nothing else)."""

    def find_spec(self, fullname: str, path: object = None, target: object = None):
        if fullname not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, _Alias())


def install() -> None:
    """Answer for the old names from now on (once per process: a second call changes nothing), and show MuBlE's
    deprecation warnings.

    They are meant for whoever runs a package written the old way, who would otherwise never see them: Python
    shows a ``DeprecationWarning`` only when ``__main__`` causes it. Shown once per place, unless the user chose
    warning filters (``-W``, ``PYTHONWARNINGS``)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())
    if not sys.warnoptions:
        warnings.filterwarnings("default", category=MubleDeprecationWarning)
