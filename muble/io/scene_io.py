"""SHOP-VRB2 scene files: parse and validate dictionaries into ``SceneGraph`` and back, losslessly."""
from __future__ import annotations

import codecs
import json
import math
import os
import stat
from pathlib import Path
from typing import Any, Callable

import numpy as np

from muble.core.errors import ConfigError, SceneValidationError
from muble.core.scene import RLE, SceneGraph, SceneObject
from muble.io.atomic import write_bytes_atomic

# Bounds on what an input file may hold, checked before the work they bound. A SHOP-VRB2 scene has at most 10
# objects and MuBlE's generator places 3-7, so 1,000 leaves room for any hand-made scene while a scene of
# 10,000 (minutes of model building, gigabytes of memory) is refused at once.
MAX_OBJECTS = 1000
# Positions and extents are metres in the scene frame, the table about 1 m from the origin: anything beyond this
# is a unit or data error, not a scene (1e308 would pass as finite yet break every later step).
MAX_COORDINATE_M = 100.0
# The largest input file read (bytes), unless MUBLE_MAX_INPUT_BYTES says otherwise: a combined scene file of the
# 1,000-scene splits is about 40 MiB, so 256 MiB is generous, and well under what parsing it costs in memory.
MAX_INPUT_BYTES_ENV = "MUBLE_MAX_INPUT_BYTES"
DEFAULT_MAX_INPUT_BYTES = 256 << 20

_OBJ_REQUIRED_STR = ("file", "name", "shape", "size", "material", "colour")
_OBJ_REQUIRED_BOOL = ("stackable", "stack_base", "pickupable")
# Optional typed keys of an object: key -> attribute. Written back only when present.
_OBJ_OPTIONAL = {
    "rotation": "rotation",
    "pixel_coords": "pixel_coords",
    "movability": "movability",
    "bbox": "bbox",
    "scale_factor": "scale_factor",
    "mask": "mask",
    "stiffness": "stiffness",
}
_OBJ_KNOWN = set(_OBJ_REQUIRED_STR) | set(_OBJ_REQUIRED_BOOL) | set(_OBJ_OPTIONAL) | {
    "3d_coords", "orientation", "weight_gt", "weight", "id",
}
_SCENE_KNOWN = {
    "split", "image_index", "image_filename", "objects", "directions", "camera_params", "lamp_params",
    "table", "robot", "relationships",
}


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _number(x: Any, *, obj: int | None, field: str, positive: bool = False, bound: float | None = None) -> float:
    """``x`` as a finite float (positive, within +-``bound`` when asked); numbers in messages are short."""
    if not _is_number(x):
        raise SceneValidationError(f"expected a number, got {type(x).__name__} {_short(x)}", obj=obj, field=field)
    try:
        value = float(x)
    except OverflowError:  # an integer too large for a float
        raise SceneValidationError("must be finite, got an integer too large for a number", obj=obj,
                                   field=field) from None
    if not math.isfinite(value):
        raise SceneValidationError(f"must be finite, got {value}", obj=obj, field=field)
    if positive and value <= 0:
        raise SceneValidationError(f"must be positive, got {value:.6g}", obj=obj, field=field)
    if bound is not None and abs(value) > bound:
        raise SceneValidationError(f"must lie within +-{bound:g} m of the scene origin (the table is about 1 m "
                                   f"away), got {value:.6g}: check the units", obj=obj, field=field)
    return value


def _short(x: Any) -> str:
    """A value's repr cut to 40 characters, without converting a huge integer to text first."""
    if isinstance(x, int) and not isinstance(x, bool) and abs(x) > 10**40:
        return "(an integer of more than 40 digits)"
    return f"{x!r:.40}"


def _vector(x: Any, n: int, *, obj: int | None, field: str, bound: float | None = None) -> np.ndarray:
    if not isinstance(x, list) or len(x) != n:
        got = f"a list of {len(x)}" if isinstance(x, list) else _short(x)  # no repr of a huge list
        raise SceneValidationError(f"expected a list of {n} numbers, got {got}", obj=obj, field=field)
    return np.array([_number(v, obj=obj, field=field, bound=bound) for v in x], dtype=float)


def _string(x: Any, *, obj: int | None, field: str) -> str:
    if not isinstance(x, str):
        raise SceneValidationError(f"expected a string, got {type(x).__name__}", obj=obj, field=field)
    return x


def _bool(x: Any, *, obj: int | None, field: str) -> bool:
    if not isinstance(x, bool):
        raise SceneValidationError(f"expected true or false, got {x!r:.40}", obj=obj, field=field)
    return x


def _rle(x: Any, *, obj: int | None, field: str) -> RLE:
    if not isinstance(x, dict) or set(x) != {"size", "counts"}:
        raise SceneValidationError("expected a COCO RLE {size: [h, w], counts: str}", obj=obj, field=field)
    size = x["size"]
    if (not isinstance(size, list) or len(size) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in size)):
        raise SceneValidationError(f"RLE size must be [height, width], got {size!r:.40}", obj=obj, field=field)
    if not isinstance(x["counts"], str):
        raise SceneValidationError("RLE counts must be a string (compressed COCO RLE)", obj=obj, field=field)
    return RLE(size=list(size), counts=x["counts"])


def _bbox(x: Any, *, obj: int) -> dict[str, float] | list:
    if isinstance(x, dict):
        if set(x) != {"x", "y", "z"}:
            raise SceneValidationError("bbox extents need exactly the keys x, y, z", obj=obj, field="bbox")
        return {k: _number(x[k], obj=obj, field="bbox", bound=MAX_COORDINATE_M) for k in ("x", "y", "z")}
    if isinstance(x, list) and len(x) == 8:
        return [_vector(c, 3, obj=obj, field="bbox", bound=MAX_COORDINATE_M).tolist() for c in x]
    raise SceneValidationError("bbox must be extents {x, y, z} or a list of 8 corners", obj=obj, field="bbox")


_OPTIONAL_PARSERS: dict[str, Callable[[Any, int], Any]] = {
    "rotation": lambda v, i: _number(v, obj=i, field="rotation"),
    "pixel_coords": lambda v, i: (_vector(v, 3, obj=i, field="pixel_coords"), list(v))[1],
    "movability": lambda v, i: _string(v, obj=i, field="movability"),
    "bbox": lambda v, i: _bbox(v, obj=i),
    "scale_factor": lambda v, i: _number(v, obj=i, field="scale_factor", positive=True),
    "mask": lambda v, i: _rle(v, obj=i, field="mask"),
    "stiffness": lambda v, i: _number(v, obj=i, field="stiffness", positive=True),
}


def object_from_dict(d: Any, index: int) -> SceneObject:
    """One object of a scene file, validated: a ``SceneValidationError`` names object ``index`` and the field."""
    if not isinstance(d, dict):
        raise SceneValidationError(f"expected an object (dict), got {type(d).__name__}", obj=index)
    for key in (*_OBJ_REQUIRED_STR, *_OBJ_REQUIRED_BOOL, "3d_coords", "orientation", "weight_gt"):
        if key not in d:
            raise SceneValidationError("missing required field", obj=index, field=key)
    strings = {k: _string(d[k], obj=index, field=k) for k in _OBJ_REQUIRED_STR}
    flags: dict[str, Any] = {k: _bool(d[k], obj=index, field=k) for k in _OBJ_REQUIRED_BOOL}
    position = _vector(d["3d_coords"], 3, obj=index, field="3d_coords", bound=MAX_COORDINATE_M)
    orientation = _vector(d["orientation"], 4, obj=index, field="orientation")
    norm = float(np.linalg.norm(orientation))
    if abs(norm - 1.0) > 1e-2:
        raise SceneValidationError(f"quaternion must have unit norm, has {norm:.4f}", obj=index, field="orientation")
    weight = d.get("weight")
    if weight is not None:
        weight = _number(weight, obj=index, field="weight")
    obj_id = d.get("id", index)
    if not isinstance(obj_id, int) or isinstance(obj_id, bool) or obj_id < 0:
        raise SceneValidationError(f"id must be a non-negative integer, got {obj_id!r:.40}", obj=index, field="id")
    optional: dict[str, Any] = {attr: _OPTIONAL_PARSERS[key](d[key], index) for key, attr in _OBJ_OPTIONAL.items() if key in d}
    return SceneObject(
        id=obj_id,
        model=strings["file"],
        name=strings["name"],
        shape=strings["shape"],
        size=strings["size"],
        material=strings["material"],
        colour=strings["colour"],
        position=position,
        orientation=orientation,
        weight_gt=_number(d["weight_gt"], obj=index, field="weight_gt", positive=True),
        weight=weight,
        **flags,
        **optional,
        extra={k: v for k, v in d.items() if k not in _OBJ_KNOWN},
        explicit_id="id" in d,
    )


def object_to_dict(o: SceneObject) -> dict[str, Any]:
    """One object as a scene file holds it (what ``object_from_dict`` reads)."""
    d: dict[str, Any] = {}
    if o.explicit_id:
        d["id"] = o.id
    d.update(file=o.model, name=o.name, shape=o.shape, size=o.size, material=o.material)
    d["3d_coords"] = o.position.tolist()
    d["orientation"] = o.orientation.tolist()
    if o.rotation is not None:
        d["rotation"] = o.rotation
    if o.pixel_coords is not None:
        d["pixel_coords"] = list(o.pixel_coords)
    d["colour"] = o.colour
    if o.weight_gt is not None:  # None in an agent's view of the scene
        d["weight_gt"] = o.weight_gt
    d["weight"] = o.weight
    for key in ("movability", "bbox", "scale_factor"):
        if getattr(o, key) is not None:
            d[key] = getattr(o, key)
    d.update(stackable=o.stackable, stack_base=o.stack_base, pickupable=o.pickupable)
    if o.mask is not None:
        d["mask"] = o.mask.to_dict()
    if o.stiffness is not None:
        d["stiffness"] = o.stiffness
    d.update(o.extra)
    return d


def _relationships(x: Any, n_ids: set[int]) -> dict[str, list[list[int]]]:
    if not isinstance(x, dict):
        raise SceneValidationError("expected a dict of relation -> lists", field="relationships")
    out = {}
    for rel, rows in x.items():
        if not isinstance(rows, list) or not all(isinstance(r, list) for r in rows):
            raise SceneValidationError(f"relation '{rel}' must be a list of lists of ids", field="relationships")
        for row in rows:
            for v in row:
                if not isinstance(v, int) or isinstance(v, bool) or v not in n_ids:
                    raise SceneValidationError(f"relation '{rel}' names unknown object {v!r:.20}",
                                               field="relationships")
        out[rel] = [list(r) for r in rows]
    return out


def _masked_part(x: Any, field: str) -> dict[str, Any]:
    if not isinstance(x, dict):
        raise SceneValidationError("expected a dict such as {mask: RLE}", field=field)
    return {k: _rle(v, obj=None, field=f"{field}.mask") if k == "mask" else v for k, v in x.items()}


def _unmasked_part(x: dict[str, Any]) -> dict[str, Any]:
    return {k: v.to_dict() if isinstance(v, RLE) else v for k, v in x.items()}


def scene_from_dict(d: Any) -> SceneGraph:
    """Parse one scene dictionary; raises ``SceneValidationError`` naming the object and field at fault."""
    if not isinstance(d, dict):
        raise SceneValidationError(f"a scene must be a JSON object, got {type(d).__name__}")
    if "objects" not in d:
        raise SceneValidationError("missing required field", field="objects")
    if not isinstance(d["objects"], list):
        raise SceneValidationError("expected a list of objects", field="objects")
    if len(d["objects"]) > MAX_OBJECTS:
        raise SceneValidationError(f"the scene has {len(d['objects'])} objects; a scene may hold at most "
                                   f"{MAX_OBJECTS} (SHOP-VRB2 scenes have up to 10): remove objects or split the "
                                   "scene", field="objects")
    objects = [object_from_dict(o, i) for i, o in enumerate(d["objects"])]
    seen: dict[int, int] = {}
    for i, o in enumerate(objects):
        if o.id in seen:
            raise SceneValidationError(f"duplicate id {o.id} (also used by object {seen[o.id]})", obj=i, field="id")
        seen[o.id] = i
    scene = SceneGraph(objects=objects, extra={k: v for k, v in d.items() if k not in _SCENE_KNOWN})
    if "split" in d:
        scene.split = _string(d["split"], obj=None, field="split")
    if "image_filename" in d:
        scene.image_filename = _string(d["image_filename"], obj=None, field="image_filename")
    if "image_index" in d:
        if not isinstance(d["image_index"], int) or isinstance(d["image_index"], bool):
            raise SceneValidationError("expected an integer", field="image_index")
        scene.image_index = d["image_index"]
    if "directions" in d:
        if not isinstance(d["directions"], dict):
            raise SceneValidationError("expected a dict of direction -> [x, y, z]", field="directions")
        scene.directions = {k: _vector(v, 3, obj=None, field=f"directions.{k}").tolist()
                            for k, v in d["directions"].items()}
    for key in ("camera_params", "lamp_params"):
        if key in d:
            if not isinstance(d[key], dict):
                raise SceneValidationError("expected a dict", field=key)
            setattr(scene, key, d[key])
    if "table" in d:
        scene.table = _masked_part(d["table"], "table")
    if "robot" in d:
        scene.robot = _masked_part(d["robot"], "robot")
    if "relationships" in d:
        scene.relationships = _relationships(d["relationships"], set(seen))
    return scene


def scene_to_dict(s: SceneGraph) -> dict[str, Any]:
    """The SHOP-VRB2 dictionary of a scene (key order as in the original release)."""
    d: dict[str, Any] = {"split": s.split, "image_index": s.image_index, "image_filename": s.image_filename,
                         "objects": [object_to_dict(o) for o in s.objects]}
    if s.directions is not None:
        d["directions"] = s.directions
    if s.camera_params is not None:
        d["camera_params"] = s.camera_params
    if s.lamp_params is not None:
        d["lamp_params"] = s.lamp_params
    if s.table is not None:
        d["table"] = _unmasked_part(s.table)
    if s.robot is not None:
        d["robot"] = _unmasked_part(s.robot)
    if s.relationships is not None:
        d["relationships"] = s.relationships
    d.update(s.extra)
    return d


class _NonFiniteConstant(ValueError):
    pass


def validate_scene(scene: SceneGraph) -> None:
    """Raise ``SceneValidationError`` if ``scene`` breaks the schema (it round-trips through the loader)."""
    scene_from_dict(scene_to_dict(scene))


def _reject_constant(name: str) -> Any:
    raise _NonFiniteConstant(name)


def _looks_utf16(raw: bytes) -> bool:
    """A UTF-16 byte-order mark, or ASCII text with every other byte zero (UTF-16 without a mark)."""
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return True
    head = raw[:16]
    return len(head) >= 4 and (set(head[1::2]) == {0} or set(head[0::2]) == {0})


def _ends_early(text: str) -> bool:
    """Whether the text stops inside a string or with brackets still open (a file cut short)."""
    depth, in_string, escaped = 0, False, False
    for ch in text:
        if escaped:
            escaped = False
        elif in_string:
            escaped, in_string = ch == "\\", ch != '"'
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
    return in_string or depth > 0 or not text.strip()


def max_input_bytes() -> int:
    """The largest input file MuBlE reads: ``MUBLE_MAX_INPUT_BYTES`` (a number of bytes) or 256 MiB."""
    text = os.environ.get(MAX_INPUT_BYTES_ENV, "").strip()
    if not text:
        return DEFAULT_MAX_INPUT_BYTES
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value <= 0:
        raise ConfigError(f"{MAX_INPUT_BYTES_ENV}={text[:40]!r} is not a positive number of bytes; set it to e.g. "
                          f"{2 * DEFAULT_MAX_INPUT_BYTES} or unset it (default {DEFAULT_MAX_INPUT_BYTES})")
    return value


def _file_kind(mode: int) -> str:
    kinds = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character "
             "device"), (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))
    return next((name for test, name in kinds if test(mode)), "not a regular file")


def _size(n: int) -> str:
    return f"{n / (1 << 30):.1f} GiB" if n >= 1 << 30 else f"{n / (1 << 20):.1f} MiB"


def _unreadable(path: str | Path, e: OSError) -> SceneValidationError:
    what = "does not exist" if isinstance(e, FileNotFoundError) else f"cannot be read ({e.strerror or e})"
    return SceneValidationError(f"{path} {what}")


def _check_input(path: str | Path, st: os.stat_result, limit: int) -> None:
    if not stat.S_ISREG(st.st_mode):
        raise SceneValidationError(f"{path} cannot be read as a file: it is {_file_kind(st.st_mode)}, not a regular "
                                   "file; pass the path of a file")
    if st.st_size > limit:
        raise SceneValidationError(f"{path} has {_size(st.st_size)}; MuBlE reads input files of at most "
                                   f"{_size(limit)}: check that this is the file meant, or raise the limit "
                                   f"with {MAX_INPUT_BYTES_ENV}=BYTES")


def check_input_file(path: str | Path) -> int:
    """The size of an input file after checking, without opening it, that it is a regular file (not a FIFO,
    device or folder, which could block or never end) within ``max_input_bytes()``; ``SceneValidationError``
    naming the file and what to change otherwise."""
    limit = max_input_bytes()
    try:
        st = os.stat(path)
    except OSError as e:
        raise _unreadable(path, e) from e
    _check_input(path, st, limit)
    return st.st_size


def read_input_bytes(path: str | Path) -> bytes:
    """The bytes of an input file, read only if ``check_input_file`` passes; the file is opened without blocking
    and checked again, so one swapped for a FIFO or device meanwhile is refused too, and at most the limit is
    read even from a file that grows."""
    check_input_file(path)
    limit = max_input_bytes()
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as e:
        raise _unreadable(path, e) from e
    with os.fdopen(fd, "rb") as f:
        _check_input(path, os.fstat(fd), limit)
        os.set_blocking(fd, True)
        try:
            raw = f.read(limit + 1)
        except OSError as e:
            raise _unreadable(path, e) from e
    if len(raw) > limit:
        raise SceneValidationError(f"{path} grew beyond {_size(limit)} while it was read; MuBlE reads input files "
                                   f"of at most that: pass a finished file, or raise the limit with "
                                   f"{MAX_INPUT_BYTES_ENV}=BYTES")
    return raw


def read_json(path: str | Path) -> Any:
    """The value in a JSON file, strictly: UTF-8 text (a UTF-8 byte-order mark is allowed) holding one JSON value,
    without ``NaN`` or ``Infinity`` (not JSON, though Python's json module writes them).

    Anything else raises ``SceneValidationError`` naming the file and what is wrong with it: missing or unreadable,
    not a regular file (a FIFO, a device) or over the size limit (``read_input_bytes``), UTF-16 or binary,
    truncated or malformed.
    """
    raw = read_input_bytes(path)
    if _looks_utf16(raw):
        raise SceneValidationError(f"{path} is UTF-16 text; JSON files must be UTF-8: save it again as UTF-8")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise SceneValidationError(f"{path} is not UTF-8 text (byte 0x{raw[e.start]:02x} at offset {e.start}); "
                                   "it is binary or in another encoding: write it again as UTF-8 JSON") from e
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except _NonFiniteConstant as e:
        raise SceneValidationError(f"{path} contains {e}, which is not a JSON number: write a finite number "
                                   "(or null where a value may be missing)") from e
    except json.JSONDecodeError as e:
        truncated = " (the file ends early: truncated?)" if _ends_early(text) else ""
        raise SceneValidationError(f"{path} is not valid JSON{truncated}: {e}") from e
    except ValueError as e:  # e.g. an integer literal longer than Python converts
        raise SceneValidationError(f"{path} is not valid JSON: {e}") from e
    except RecursionError as e:
        raise SceneValidationError(f"{path} nests JSON values too deeply to be a SHOP-VRB2 file") from e


def in_file(error: SceneValidationError, path: str | Path) -> SceneValidationError:
    """The same error with the file it comes from named first (object and field kept)."""
    named = SceneValidationError(f"{path}: {error}")
    named.obj, named.field = error.obj, error.field
    return named


def load_scene(path: str | Path) -> SceneGraph:
    """Load a single-scene file; a ``SceneValidationError`` names the file, and the object and field at fault."""
    data = read_json(path)
    try:
        return scene_from_dict(data)
    except SceneValidationError as e:
        raise in_file(e, path) from e


def load_scenes(path: str | Path) -> tuple[dict[str, Any], list[SceneGraph]]:
    """Load a combined ``{info, scenes}`` file; returns the info block and the scenes."""
    data = read_json(path)
    if not isinstance(data, dict) or not isinstance(data.get("scenes"), list):
        raise SceneValidationError(f"{path}: a combined scene file needs a 'scenes' list", field="scenes")
    info = data.get("info", {})
    if not isinstance(info, dict):
        raise SceneValidationError("expected a dict", field="info")
    scenes = []
    for i, s in enumerate(data["scenes"]):
        try:
            scenes.append(scene_from_dict(s))
        except SceneValidationError as e:
            raise SceneValidationError(f"scene {i}: {e}", obj=None, field=None) from e
    return info, scenes


def write_json_atomic(path: str | Path, data: Any, **dump_kwargs: Any) -> None:
    """Write JSON to ``path`` through a temporary file and a rename: readers never see a partial file."""
    write_bytes_atomic(path, json.dumps(data, **dump_kwargs).encode("utf-8"))


def save_scene(path: str | Path, scene: SceneGraph) -> None:
    """Write a single-scene file atomically (``load_scene`` reads it)."""
    write_json_atomic(path, scene_to_dict(scene))


def save_scenes(path: str | Path, scenes: list[SceneGraph], info: dict[str, Any] | None = None) -> None:
    """Write a combined ``{info, scenes}`` file atomically (``load_scenes`` reads it)."""
    write_json_atomic(path, {"info": info or {}, "scenes": [scene_to_dict(s) for s in scenes]})
