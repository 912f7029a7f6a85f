"""Content keys of visual meshes, so per-mesh work (FCL BVHs, render meshes) is done once per distinct mesh."""
from __future__ import annotations

import hashlib

import numpy as np

from muble.core.objects import ObjectModel

_KEY_MEMO: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, bytes]] = {}
_KEY_MEMO_SIZE = 4096


def mesh_key(model: ObjectModel) -> bytes:
    """A content key of ``model``'s visual mesh (vertices and faces).

    Read-only arrays (object sets share them between builds) are hashed once; the memo holds the arrays so
    their ids cannot be reused while the entry lives.
    """
    vertices, faces = model.visual.vertices, model.visual.faces
    frozen = isinstance(vertices, np.ndarray) and isinstance(faces, np.ndarray) and not (
        vertices.flags.writeable or faces.flags.writeable)
    if frozen:
        hit = _KEY_MEMO.get((id(vertices), id(faces)))
        if hit is not None and hit[0] is vertices and hit[1] is faces:
            return hit[2]
    h = hashlib.blake2b(digest_size=16)
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    h.update(np.array(v.shape + f.shape, np.int64).tobytes())
    h.update(v.tobytes())
    h.update(f.tobytes())
    key = h.digest()
    if frozen:
        if len(_KEY_MEMO) >= _KEY_MEMO_SIZE:
            _KEY_MEMO.clear()
        _KEY_MEMO[(id(vertices), id(faces))] = (vertices, faces, key)
    return key
