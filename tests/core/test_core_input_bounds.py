"""Input files are read within bounds: anything but a regular file (a FIFO, a device, a folder) and any file over
the size limit is refused before it is read, and a scene's object count and coordinates are bounded, each with a
``SceneValidationError`` that names the file and what to change.

The command-line cases run ``muble render`` as a subprocess under a 4 GB address-space limit: each must end
within 10 s with exit code 2, one message and no output folder (before these bounds, ``/dev/zero`` grew the
process to 24 GB and a FIFO blocked it for ever).
"""
from __future__ import annotations

import copy
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import pytest

from muble.core.errors import ConfigError, SceneValidationError
from muble.io.scene_io import (DEFAULT_MAX_INPUT_BYTES, MAX_COORDINATE_M, MAX_INPUT_BYTES_ENV, MAX_OBJECTS,
                                 load_scene, read_json, scene_from_dict)

REPO = Path(__file__).resolve().parents[2]
MEMORY_LIMIT = 4 << 30  # bytes of address space for the command
COMMAND_LIMIT_S = 10.0

OBJECT = {"file": "mug1", "name": "mug", "shape": "cylindrical", "size": "small", "material": "ceramic",
          "colour": "red", "3d_coords": [0.5, 0.0, 0.0], "orientation": [1.0, 0.0, 0.0, 0.0], "weight_gt": 250.0,
          "stackable": False, "stack_base": False, "pickupable": True}


def scene(n: int = 1, **changes) -> dict:
    return {"objects": [{**copy.deepcopy(OBJECT), **changes} for _ in range(n)]}


# --------------------------------------------------------------------------------------------- the loaders
def test_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "scene.json"
    os.mkfifo(fifo)
    with pytest.raises(SceneValidationError, match="FIFO") as err:
        read_json(fifo)  # no writer: opening it for reading would block for ever
    assert str(fifo) in str(err.value) and "regular file" in str(err.value)


def test_a_device_is_refused():
    with pytest.raises(SceneValidationError, match="character device"):
        load_scene("/dev/zero")


def test_a_file_over_the_limit_is_refused_unread(tmp_path):
    big = tmp_path / "big.json"
    with open(big, "wb") as f:
        f.truncate(DEFAULT_MAX_INPUT_BYTES + 1)  # sparse: no disk used
    with pytest.raises(SceneValidationError) as err:
        load_scene(big)
    assert str(big) in str(err.value) and MAX_INPUT_BYTES_ENV in str(err.value)


def test_the_size_limit_is_configurable(tmp_path, monkeypatch):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene(3)))
    size = path.stat().st_size
    monkeypatch.setenv(MAX_INPUT_BYTES_ENV, str(size - 1))
    with pytest.raises(SceneValidationError, match=MAX_INPUT_BYTES_ENV):
        load_scene(path)
    monkeypatch.setenv(MAX_INPUT_BYTES_ENV, str(size))
    assert len(load_scene(path).objects) == 3
    for bad in ("-5", "0", "lots"):
        monkeypatch.setenv(MAX_INPUT_BYTES_ENV, bad)
        with pytest.raises(ConfigError, match=MAX_INPUT_BYTES_ENV):
            load_scene(path)


def test_object_count_is_bounded():
    assert len(scene_from_dict(scene(MAX_OBJECTS)).objects) == MAX_OBJECTS
    with pytest.raises(SceneValidationError, match=f"at most {MAX_OBJECTS}") as err:
        scene_from_dict(scene(MAX_OBJECTS + 1))
    assert err.value.field == "objects"


@pytest.mark.parametrize("position", [[1e308, 0.0, 0.0], [0.0, -101.0, 0.0], [0, 0, 10**400]])
def test_coordinates_are_bounded_and_printed_short(tmp_path, position):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps({"objects": [OBJECT, {**OBJECT, "3d_coords": position}]}))
    with pytest.raises(SceneValidationError) as err:
        load_scene(path)
    assert (err.value.obj, err.value.field) == (1, "3d_coords")
    assert str(err.value).startswith(f"{path}: object 1, field '3d_coords'") and len(str(err.value)) < 400


def test_coordinates_within_the_bound_load():
    edge = scene(1, **{"3d_coords": [MAX_COORDINATE_M, -MAX_COORDINATE_M, 0.0]})
    assert scene_from_dict(edge).objects[0].position[0] == MAX_COORDINATE_M


# ------------------------------------------------------------------------------------------ muble render
def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def render(path: Path | str, out: Path) -> tuple[subprocess.CompletedProcess, float]:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    start = time.monotonic()
    result = subprocess.run([sys.executable, "-m", "muble.app.cli", "render", str(path), "--out", str(out)],
                            cwd=REPO, env=env, capture_output=True, text=True, timeout=COMMAND_LIMIT_S,
                            preexec_fn=_limit_memory)
    return result, time.monotonic() - start


def _fifo(tmp_path: Path) -> Path:
    os.mkfifo(tmp_path / "fifo.json")
    return tmp_path / "fifo.json"


def _sparse_3gb(tmp_path: Path) -> Path:
    path = tmp_path / "big.json"
    with open(path, "wb") as f:
        f.truncate(3 << 30)
    return path


def _many_objects(tmp_path: Path) -> Path:
    path = tmp_path / "many.json"
    path.write_text(json.dumps(scene(10_000)))
    return path


@pytest.mark.parametrize("make, says", [
    (lambda tmp: Path("/dev/zero"), "character device"),
    (_fifo, "FIFO"),
    (_sparse_3gb, "3.0 GiB"),
    (_many_objects, "10000 objects"),
], ids=["dev-zero", "fifo", "sparse-3GB", "10000-objects"])
def test_render_refuses_within_bounds(tmp_path, make, says):
    path = make(tmp_path)
    out = tmp_path / "renders"
    result, seconds = render(path, out)
    assert result.returncode == 2, result.stderr[-2000:]
    assert seconds < COMMAND_LIMIT_S
    message = result.stderr.strip()
    assert says in message and str(path.name) in message, message
    assert "Traceback" not in result.stderr and len(message.splitlines()) == 1, message
    assert not out.exists()
