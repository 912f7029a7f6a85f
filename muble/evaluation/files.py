"""Evaluating on scene and instruction files in the original SHOP-VRB2/MuBlE layout.

    muble eval agent=oracle dataset.scenes_file=NS_AP_demo_scenes.json \\
        dataset.instructions_file=NS_AP_demo_instructions.json

The instruction file is ``{info, instructions[]}``; the scene file is a combined ``{info, scenes[]}`` file, a
single scene, or a folder of single-scene files. Each instruction is one episode (its index in the instruction
file), run on the scene with the same ``image_filename`` or, failing that, the same ``image_index``. The episodes
form one split named after the instruction file (``NS_AP_demo_instructions``), reported like a generated split.
A malformed instruction or scene, or an instruction whose scene is not there, is that episode's
``invalid_data``; only files that cannot be read at all stop the run before it starts.
"""
from __future__ import annotations

import functools
import hashlib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from muble.core.errors import ConfigError, MubleError, SceneValidationError
from muble.core.interfaces import Instruction
from muble.core.scene import SceneGraph

_PLAIN = re.compile(r"[^A-Za-z0-9_-]+")


@dataclass(frozen=True)
class EpisodeFiles:
    """The raw records of an instruction file and of its scenes (parsed per episode, so one bad record fails
    only its own episode)."""

    instructions: tuple[Any, ...]
    scenes: tuple[Any, ...]

    def instruction(self, index: int) -> tuple[dict[str, Any], Instruction]:
        from muble.io.instructions_io import instruction_from_dict

        record = self.instructions[index]
        return record, instruction_from_dict(record, index)

    def scene_for(self, instruction: Instruction) -> SceneGraph:
        """The scene of ``instruction``: the one with its ``image_filename``, else the one with its
        ``image_index``; ``SceneValidationError`` when neither is there or the scene record is malformed."""
        from muble.io.scene_io import scene_from_dict

        def find(key: str, value: Any) -> list[int]:
            return [i for i, s in enumerate(self.scenes) if isinstance(s, dict) and s.get(key) == value]

        found = find("image_filename", instruction.image_filename) if instruction.image_filename else []
        if not found and instruction.image_index is not None:
            found = find("image_index", instruction.image_index)
        if not found:
            raise SceneValidationError(f"no scene has image_filename {instruction.image_filename!r} or image_index "
                                       f"{instruction.image_index!r}; add the scene to the scene file",
                                       field="image_index")
        if len(found) > 1:
            raise SceneValidationError(f"{len(found)} scenes match image_filename {instruction.image_filename!r} / "
                                       f"image_index {instruction.image_index!r} (scene records {found}); keep one",
                                       field="image_index")
        try:
            return scene_from_dict(self.scenes[found[0]])
        except SceneValidationError as e:
            raise SceneValidationError(f"scene record {found[0]}: {e}") from e


def split_name(instructions_file: str | Path) -> str:
    """The split the episodes are reported under: the instruction file's name as a plain word."""
    return _PLAIN.sub("_", Path(instructions_file).stem).strip("_")[:64] or "files"


def _scene_records(path: Path) -> list[Any]:
    from muble.io.scene_io import read_json

    if path.is_dir():
        return [read_json(p) for p in sorted(path.glob("*.json"))]
    data = read_json(path)
    if isinstance(data, dict) and isinstance(data.get("scenes"), list):
        return list(data["scenes"])
    if isinstance(data, dict) and isinstance(data.get("objects"), list):
        return [data]
    raise SceneValidationError(f"{path}: expected a combined scene file {{info, scenes}}, a single scene "
                               "{objects, …} or a folder of scene files", field="scenes")


@functools.lru_cache(maxsize=4)
def _load(scenes_file: str, instructions_file: str, stamp: tuple) -> EpisodeFiles:
    from muble.io.scene_io import read_json

    data = read_json(instructions_file)
    if not isinstance(data, dict) or not isinstance(data.get("instructions"), list):
        raise SceneValidationError(f"{instructions_file}: an instruction file needs an 'instructions' list",
                                   field="instructions")
    return EpisodeFiles(tuple(data["instructions"]), tuple(_scene_records(Path(scenes_file))))


def _stamp(*paths: str) -> tuple:
    out = []
    for p in paths:
        path = Path(p)
        files = sorted(path.glob("*.json")) if path.is_dir() else [path]
        out.append(tuple((str(f), f.stat().st_mtime_ns, f.stat().st_size) for f in files))
    return tuple(out)


def load_files(dataset: Any) -> EpisodeFiles:
    """The files named by ``dataset.scenes_file`` and ``dataset.instructions_file`` (cached per process)."""
    scenes_file, instructions_file = str(dataset["scenes_file"]), str(dataset["instructions_file"])
    return _load(scenes_file, instructions_file, _stamp(scenes_file, instructions_file))


def uses_files(dataset: Any) -> bool:
    """Whether the configured dataset is a pair of files rather than a generated dataset folder."""
    return bool(dataset.get("scenes_file") or dataset.get("instructions_file"))


def check_files(dataset: Any) -> tuple[str, list[int], str]:
    """(split name, episode indices, sha256 of both files) after checking that both files are given and read."""
    scenes_file, instructions_file = dataset.get("scenes_file"), dataset.get("instructions_file")
    if not scenes_file or not instructions_file:
        raise ConfigError("set both dataset.scenes_file= and dataset.instructions_file= (original-format files), "
                          f"got scenes_file={scenes_file!r}, instructions_file={instructions_file!r}")
    for name, path in (("scenes_file", scenes_file), ("instructions_file", instructions_file)):
        if not Path(path).exists():
            raise ConfigError(f"dataset.{name}={path} does not exist")
    try:
        files = load_files(dataset)
    except MubleError as e:
        raise ConfigError(f"cannot read the files to evaluate: {e}") from e
    if not files.instructions:
        raise ConfigError(f"{instructions_file} holds no instruction to evaluate")
    from muble.io.scene_io import read_input_bytes

    digest = hashlib.sha256()
    for path in (scenes_file, instructions_file):
        p = Path(path)
        for f in (sorted(p.glob("*.json")) if p.is_dir() else [p]):
            try:
                digest.update(read_input_bytes(f))  # bounded and typed, as the loaders read it
            except MubleError as e:
                raise ConfigError(f"cannot read the files to evaluate: {e}") from e
    return split_name(instructions_file), list(range(len(files.instructions))), digest.hexdigest()
