"""A mesh atlas: GPU-side mesh storage reused across scenes that share meshes.

Uploading a model to the GPU (``MjrContext``) costs ~70 ms here, far more than drawing a small frame, and a
scene generator builds a new model for every scene from a small catalogue of meshes. The atlas is a model that
holds each distinct mesh once; a scene model whose meshes are all in it is drawn with the atlas's context by
renumbering its mesh ids. Meshes are matched by their compiled vertex and face bytes, so a match is exact.
"""
from __future__ import annotations

import hashlib
import logging

import numpy as np

log = logging.getLogger(__name__)


def mesh_keys(model) -> list[bytes]:
    """A content key per mesh of ``model`` (vertices and faces)."""
    keys = []
    for i in range(model.nmesh):
        v0, nv = model.mesh_vertadr[i], model.mesh_vertnum[i]
        f0, nf = model.mesh_faceadr[i], model.mesh_facenum[i]
        h = hashlib.blake2b(digest_size=16)
        h.update(np.ascontiguousarray(model.mesh_vert[v0:v0 + nv]).tobytes())
        h.update(np.ascontiguousarray(model.mesh_face[f0:f0 + nf]).tobytes())
        keys.append(h.digest())
    return keys


def atlas_compatible(model) -> bool:
    """Only untextured, material-free models can borrow another model's GPU data."""
    return model.ntex == 0 and model.nmat == 0 and model.nskin == 0 and model.nhfield == 0 and model.nflex == 0


class MeshAtlas:
    """Distinct meshes seen so far, compiled into one model (``self.model``) that a GL context is made from."""

    def __init__(self, max_meshes: int = 1024):
        self.max_meshes = max_meshes
        self.model = None
        self._index: dict[bytes, int] = {}
        self._sources: list[tuple[np.ndarray, np.ndarray]] = []

    def remap(self, model) -> np.ndarray | None:
        """Atlas mesh id of each mesh of ``model``, or ``None`` when some mesh is not in the atlas yet."""
        ids = [self._index.get(k) for k in mesh_keys(model)]
        if any(i is None for i in ids):
            return None
        return np.array(ids, dtype=np.int32)

    def extend(self, model, width: int, height: int) -> np.ndarray:
        """Add ``model``'s missing meshes, recompile the atlas model and return the mesh id remap."""
        import mujoco

        keys = mesh_keys(model)
        if len(self._index) + len(keys) > self.max_meshes:
            self._index.clear()
            self._sources.clear()
        for i, key in enumerate(keys):
            if key in self._index:
                continue
            v0, nv = model.mesh_vertadr[i], model.mesh_vertnum[i]
            f0, nf = model.mesh_faceadr[i], model.mesh_facenum[i]
            self._index[key] = len(self._sources)
            self._sources.append((np.array(model.mesh_vert[v0:v0 + nv], dtype=np.float64),
                                  np.array(model.mesh_face[f0:f0 + nf], dtype=np.int32)))
        spec = mujoco.MjSpec()
        spec.visual.global_.offwidth = int(width)
        spec.visual.global_.offheight = int(height)
        body = spec.worldbody.add_body(name="atlas")
        for j, (verts, faces) in enumerate(self._sources):
            spec.add_mesh(name=f"atlas_mesh_{j}", uservert=verts.ravel().tolist(), userface=faces.ravel().tolist())
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"atlas_mesh_{j}", contype=0, conaffinity=0,
                          density=0)
        self.model = spec.compile()
        # Compiled meshes are already centred, so recompiling must leave them in place; check rather than trust.
        for j, (verts, _) in enumerate(self._sources):
            a0, an = self.model.mesh_vertadr[j], self.model.mesh_vertnum[j]
            if an != len(verts) or np.abs(self.model.mesh_vert[a0:a0 + an] - verts).max() > 1e-6:
                log.debug("atlas mesh %d moved when recompiled; this model is drawn from its own context", j)
                self.model = None
                self._index.clear()
                self._sources.clear()
                return None
        log.debug("mesh atlas now holds %d meshes", len(self._sources))
        return self.remap(model)


# --- refilling a context's mesh slots ----------------------------------------------------------------------------
# A GL context keeps, besides the meshes, what ``MjrContext`` copies from the model it was made from: the textures,
# the materials' texture bindings, a display list per plane geom, and visual settings (some scaled by the model's
# extent). Two models that agree on all of that (a scene generator's scenes: the same arena and robot, other
# objects) can share one context whose mesh slots are re-uploaded (``mjr_uploadMesh``) where their contents differ.


def stage_parts(model) -> list[np.ndarray] | None:
    """Everything a GL context takes from ``model`` but its meshes, as arrays (views where they can be); None for
    models with height fields, skins or flexes, whose GPU data this does not cover."""
    if model.nhfield or model.nskin or model.nflex:
        return None
    vis, q, mp, gl = model.vis, model.vis.quality, model.vis.map, model.vis.global_
    numbers = [q.shadowsize, q.offsamples, q.numslices, q.numstacks, q.numquads, mp.zfar, mp.znear, mp.shadowclip,
               mp.shadowscale, mp.fogstart, mp.fogend, gl.linewidth, gl.offwidth, gl.offheight, model.stat.extent,
               *vis.rgba.fog]
    planes = np.flatnonzero(model.geom_type == 0)  # mjGEOM_PLANE
    return [np.asarray(numbers, dtype=np.float64), model.tex_type, model.tex_width, model.tex_height,
            model.tex_nchannel, model.tex_colorspace, model.tex_data, model.mat_texid, model.mat_texuniform,
            model.mat_texrepeat, model.geom_size[planes], model.geom_matid[planes]]


def mesh_slot_parts(model, i: int) -> list[np.ndarray]:
    """Everything ``mjr_uploadMesh`` draws mesh ``i`` from (views into ``model``): vertices, faces, normals,
    texture coordinates and the convex hull, after a header saying which of the last two it has."""
    v0, nv = model.mesh_vertadr[i], model.mesh_vertnum[i]
    f0, nf = model.mesh_faceadr[i], model.mesh_facenum[i]
    n0, nn = model.mesh_normaladr[i], model.mesh_normalnum[i]
    t0, nt = model.mesh_texcoordadr[i], model.mesh_texcoordnum[i]
    g0 = model.mesh_graphadr[i]
    parts = [np.array([t0 >= 0, g0 >= 0]), model.mesh_vert[v0:v0 + nv], model.mesh_face[f0:f0 + nf],
             model.mesh_normal[n0:n0 + nn], model.mesh_facenormal[f0:f0 + nf]]
    if t0 >= 0:
        parts += [model.mesh_texcoord[t0:t0 + nt], model.mesh_facetexcoord[f0:f0 + nf]]
    if g0 >= 0:
        nvert, nface = int(model.mesh_graph[g0]), int(model.mesh_graph[g0 + 1])
        parts.append(model.mesh_graph[g0:g0 + 2 + 3 * nvert + 6 * nface])
    return parts


def _same(parts: list[np.ndarray], kept: list[np.ndarray]) -> bool:
    return len(parts) == len(kept) and all(
        a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b) for a, b in zip(parts, kept))


class ContextContents:
    """What a GL context holds from the models it was made from or refilled with: copies of the stage's arrays
    (``stage_parts``) and of each mesh slot's (``mesh_slot_parts``), compared with another model's by value.
    Equal arrays are the match (exact, as a digest of their bytes would be, in a tenth of the time: comparing a
    robosuite scene's ~27 MB of meshes and textures takes a few ms, hashing it ~65 ms every scene)."""

    def __init__(self):
        self._stage: list[np.ndarray] | None = None  # None: the context cannot be refilled
        self._slots: list[list[np.ndarray]] = []

    def reset(self, model=None) -> None:
        """The context was made from ``model`` (None: from a model that is not to be refilled, or freed)."""
        stage = None if model is None else stage_parts(model)
        self._stage = None if stage is None else [np.array(a, copy=True) for a in stage]
        self._slots = [] if self._stage is None else [
            [np.array(a, copy=True) for a in mesh_slot_parts(model, i)] for i in range(model.nmesh)]

    def same_stage(self, model) -> bool:
        """Whether ``model`` agrees with the context on everything but its meshes."""
        stage = stage_parts(model)
        return stage is not None and self._stage is not None and _same(stage, self._stage)

    def changed_slots(self, model) -> list[int]:
        """The mesh slots whose contents ``model`` would change (slots past the kept ones count as changed)."""
        return [i for i in range(model.nmesh)
                if i >= len(self._slots) or not _same(mesh_slot_parts(model, i), self._slots[i])]

    def refilled(self, model, slots: list[int]) -> None:
        """``slots`` now hold ``model``'s meshes."""
        for i in slots:
            copies = [np.array(a, copy=True) for a in mesh_slot_parts(model, i)]
            if i < len(self._slots):
                self._slots[i] = copies
            else:
                self._slots.append(copies)
