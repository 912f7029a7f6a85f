"""Keyframe state files: the MuJoCo joint positions of an episode at each keyframe, to re-render it later.

``muble run`` writes ``keyframes/<episode>_states.npz`` beside the keyframes; ``muble render SCENE.json
--keyframes FILE.npz`` reads it and renders the same states with any renderer (Blender for photoreal frames).
The archive holds ``qpos`` (keyframes × nq, float64, MuJoCo's ``data.qpos`` of the episode's world) and, as
0-d string arrays, ``robot``, ``object_set`` and ``camera``: what the world was built from and rendered with.
Only ``qpos`` is required, so a hand-made file of states works too.
"""
from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from muble.core.errors import ConfigError

STATE_KEYS = ("robot", "object_set", "camera")


@dataclass
class KeyframeStates:
    qpos: np.ndarray  # (keyframes, nq)
    robot: str | None = None
    object_set: str | None = None
    camera: str | None = None


def keyframe_states_bytes(states: KeyframeStates) -> bytes:
    """The ``.npz`` archive of ``states`` (written through ``write_bytes_atomic`` by the caller)."""
    arrays: dict[str, Any] = {"qpos": np.asarray(states.qpos, dtype=np.float64)}
    for key in STATE_KEYS:
        value = getattr(states, key)
        if value is not None:
            arrays[key] = np.asarray(str(value))
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return buffer.getvalue()


def read_keyframe_states(path: str | Path) -> KeyframeStates:
    """Read and check a keyframe state file; a ``ConfigError`` says what is wrong with it and what to pass."""
    path = Path(path)
    hint = "pass the keyframes/<episode>_states.npz that `muble run` writes"
    if not path.is_file():
        raise ConfigError(f"--keyframes {path} " + ("is a folder" if path.is_dir() else "does not exist")
                          + f"; {hint}")
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise ConfigError(f"--keyframes {path} is not a readable .npz archive ({e}); {hint}") from e
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise ConfigError(f"--keyframes {path} is a single .npy array, not an .npz archive; {hint}")
    try:
        names = list(archive.files)
        if "qpos" not in names:
            raise ConfigError(f"--keyframes {path} has no 'qpos' array (it has: {', '.join(names) or 'none'}); "
                              f"{hint}")
        qpos = np.asarray(archive["qpos"])
        extra = {k: str(archive[k]) for k in STATE_KEYS if k in names and archive[k].ndim == 0}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise ConfigError(f"--keyframes {path}: an array in it cannot be read ({e}); {hint}") from e
    finally:
        archive.close()
    if qpos.ndim != 2 or qpos.shape[0] == 0 or not np.issubdtype(qpos.dtype, np.number):
        raise ConfigError(f"--keyframes {path}: 'qpos' must be a numeric array (keyframes, nq) with at least one "
                          f"row, got shape {qpos.shape} of {qpos.dtype}")
    if not np.all(np.isfinite(qpos)):
        rows = sorted({int(r) for r in np.argwhere(~np.isfinite(qpos))[:, 0]})
        raise ConfigError(f"--keyframes {path}: 'qpos' has NaN or infinite values in keyframe(s) {rows[:10]}")
    return KeyframeStates(qpos.astype(np.float64), **extra)
