"""Which indices of a split an evaluation covers: those the dataset records, not whichever files exist now.

``muble generate`` writes ``manifest.json`` at the dataset root with the sha256 of every file it wrote, so the
indices of a split are the ones whose scene or instruction file the manifest lists. An index whose files went
missing since is still an episode (``invalid_data``), never silently dropped. Indices with a complete instruction
file the manifest does not list (written after it, by a later or unfinished run) are evaluated too. Without a
readable manifest the instruction files present are all there is to go by, and the report says so.
"""
from __future__ import annotations

import json
import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

from muble.core.errors import ConfigError, MubleError
from muble.io.layout import PREFIX, DatasetLayout

log = logging.getLogger(__name__)

MANIFEST = "manifest.json"


@dataclass
class SplitIndices:
    """The indices of one split: those to evaluate, those skipped, and what the list was taken from."""

    split: str
    indices: list[int]  # evaluated, ascending
    skipped: list[int] = field(default_factory=list)  # the instruction file says no template applied
    source: str = "manifest"  # "manifest", or why the instruction files present were used instead


def _pattern(split: str, folder: str) -> re.Pattern[str]:
    return re.compile(rf"^{folder}{PREFIX}_{re.escape(split)}_(\d+)\.json$")


def manifest_indices(layout: DatasetLayout) -> tuple[set[int] | None, str]:
    """The indices of ``layout.split`` whose scene or instruction file the dataset's manifest lists, or None (and
    why) when there is no readable manifest with a file list."""
    path = layout.root / MANIFEST
    if not path.is_file():
        return None, f"no {MANIFEST} in {layout.root}"
    try:
        files = json.loads(path.read_text(encoding="utf-8"))["files"]
        names = list(files)
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as e:
        return None, f"{path} is unreadable ({type(e).__name__}: {e})"
    prefix = re.escape(f"{layout.split}/")
    patterns = [_pattern(layout.split, f"{prefix}{kind}/") for kind in ("scenes", "instructions")]
    return {int(m.group(1)) for name in names if isinstance(name, str)
            for m in (p.match(name) for p in patterns) if m}, "manifest"


def present_indices(layout: DatasetLayout) -> set[int]:
    """The indices with an instruction file (written last for an index, so the generator finished them)."""
    folder = layout.split_dir / "instructions"
    pattern = _pattern(layout.split, "")
    return {int(m.group(1)) for p in (folder.iterdir() if folder.is_dir() else ()) if (m := pattern.match(p.name))}


def _says_no_template(path: Path) -> bool:
    """The instruction file is readable and records that no template applied (``"instruction": null``)."""
    from muble.io.instructions_io import load_instruction

    if not path.is_file():
        return False
    try:
        return load_instruction(path)[1] is None
    except MubleError:
        return False  # an unreadable file is evaluated, as invalid_data
    except Exception as e:  # a bug in reading: the episode's record will carry it
        log.warning("%s: %s: %s", path, type(e).__name__, e)
        return False


def split_indices(layout: DatasetLayout) -> SplitIndices:
    """Every index of the split the dataset records, less those its instruction file skips (no template applied)."""
    listed, source = manifest_indices(layout)
    present = present_indices(layout)
    if listed is None:
        log.warning("%s: %s; evaluating the %d indices with an instruction file", layout.split, source, len(present))
        listed = set()
    elif present - listed:
        log.warning("%s: %d indices have instruction files the manifest does not list (%s …); evaluating them too",
                    layout.split, len(present - listed), sorted(present - listed)[:5])
    indices: list[int] = []
    skipped: list[int] = []
    for index in sorted(listed | present):
        (skipped if _says_no_template(layout.split_dir / layout.instruction(index)) else indices).append(index)
    return SplitIndices(layout.split, indices, skipped, source)


def splits_present(root: Path) -> list[str]:
    """The splits of a dataset: folders with instruction files, and splits the manifest lists files of."""
    found = {p.name for p in root.iterdir() if p.is_dir() and (p / "instructions").is_dir()} if root.is_dir() else set()
    try:
        files = json.loads((root / MANIFEST).read_text(encoding="utf-8"))["files"]
        found |= {name.split("/")[0] for name in files if isinstance(name, str) and "/instructions/" in name}
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError, AttributeError):
        pass  # no manifest: the folders are all there is
    return sorted(found)


def check_split(layout: DatasetLayout) -> SplitIndices:
    """The split's indices, or a ConfigError saying how to point at a generated split."""
    found = split_indices(layout)
    if not found.indices and not found.skipped:
        present = splits_present(layout.root)
        if layout.split not in present:
            raise ConfigError(f"split '{layout.split}' is not in dataset {layout.root}; splits present: "
                              f"{', '.join(present) or '(none)'}. Set dataset.splits=[...] to one of them or "
                              f"generate it with `muble generate dataset.splits=[{layout.split}] "
                              f"dataset.root={layout.root}`")
    if not found.indices:
        raise ConfigError(f"split '{layout.split}' in {layout.root} has no index to evaluate (no instruction file "
                          "with an instruction, and none listed in the manifest); finish generating it with "
                          "`muble generate`")
    return found
