"""Simplified visual meshes for small images: the model's detailed meshes drawn from coarser copies.

A robosuite Panda's visual meshes hold some 170k triangles, most of them far smaller than a pixel of a 128x128
image; on a software rasteriser drawing them is most of such a frame. Vertex clustering snaps every vertex to the
mean of its cell on a regular grid and drops the triangles that collapse, so no surface moves further than a
cell's diagonal: with a cell under a pixel's footprint the silhouettes, and so the masks, stay where they were
(benchmarks/gym_speed.py measures the masks' IoU against the meshes as modelled).

Only the GPU copy changes: the simplified meshes are written into the model while its ``MjrContext`` is made and
the model's own arrays are put back at once, so physics and every other reader see the model as compiled.
"""
from __future__ import annotations

import hashlib
from contextlib import contextmanager
from typing import Iterator

import numpy as np

# Meshes with fewer triangles are drawn as modelled: the objects' meshes (a few hundred triangles each) cost little
# and carry the object masks; the robot's links have thousands.
SIMPLIFY_MIN_FACES = 1000


def cluster_vertices(verts: np.ndarray, faces: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(verts, faces, normals)`` of the mesh clustered on a grid of ``cell`` metres: each vertex becomes its
    cell's mean, triangles that collapse or repeat are dropped, normals are the area-weighted face normals."""
    keys = np.floor(np.asarray(verts, dtype=np.float64) / cell).astype(np.int64)
    _, cluster = np.unique(keys, axis=0, return_inverse=True)
    cluster = cluster.ravel()
    count = int(cluster.max()) + 1
    centres = np.zeros((count, 3))
    np.add.at(centres, cluster, verts)
    centres /= np.bincount(cluster, minlength=count)[:, None]
    tri = cluster[np.asarray(faces)]
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])]
    _, first = np.unique(np.sort(tri, axis=1), axis=0, return_index=True)
    tri = tri[np.sort(first)]
    used = np.unique(tri)
    renumber = np.full(count, -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    verts_out, tri = centres[used], renumber[tri]
    face_normals = np.cross(verts_out[tri[:, 1]] - verts_out[tri[:, 0]], verts_out[tri[:, 2]] - verts_out[tri[:, 0]])
    normals = np.zeros_like(verts_out)
    for corner in range(3):
        np.add.at(normals, tri[:, corner], face_normals)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    return verts_out, tri.astype(np.int32), normals


def _textured_meshes(model) -> set[int]:
    """Meshes drawn with a textured material: their texture coordinates must stay, so they are not simplified."""
    import mujoco

    textured = set()
    for g in np.flatnonzero((model.geom_type == mujoco.mjtGeom.mjGEOM_MESH) & (model.geom_dataid >= 0)):
        mat = int(model.geom_matid[g])
        if mat >= 0 and (np.asarray(model.mat_texid[mat]) >= 0).any():
            textured.add(int(model.geom_dataid[g]))
    return textured


class SimplifiedMeshes:
    """Clustered copies of a model's detailed meshes, kept by content so that a new model of the same robot (every
    scene builds one) reuses them."""

    def __init__(self, cell: float):
        self.cell = float(cell)
        self._cache: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray] | None] = {}

    def _simplified(self, model, i: int):
        v0, nv = int(model.mesh_vertadr[i]), int(model.mesh_vertnum[i])
        f0, nf = int(model.mesh_faceadr[i]), int(model.mesh_facenum[i])
        verts, faces = model.mesh_vert[v0:v0 + nv], model.mesh_face[f0:f0 + nf]
        key = hashlib.blake2b(verts.tobytes() + faces.tobytes(), digest_size=16).digest()
        if key not in self._cache:
            out = cluster_vertices(verts, faces, self.cell)
            # Kept only if it saves something and fits the mesh's own slots (the arrays cannot grow).
            fits = 0 < len(out[1]) < nf and len(out[0]) <= min(nv, int(model.mesh_normalnum[i]))
            self._cache[key] = out if fits else None
        return self._cache[key]

    @contextmanager
    def drawn_in(self, model) -> Iterator[int]:
        """Write the simplified meshes into ``model`` for the ``with`` block (make the context inside it); yields
        how many meshes were replaced. The model's arrays are restored on leaving."""
        textured = _textured_meshes(model)
        saved = []
        try:
            for i in range(model.nmesh):
                if int(model.mesh_facenum[i]) < SIMPLIFY_MIN_FACES or i in textured:
                    continue
                simplified = self._simplified(model, i)
                if simplified is None:
                    continue
                verts, faces, normals = simplified
                v0, f0, n0 = int(model.mesh_vertadr[i]), int(model.mesh_faceadr[i]), int(model.mesh_normaladr[i])
                nv, nf = len(verts), len(faces)
                saved.append((i, model.mesh_vert[v0:v0 + nv].copy(), model.mesh_normal[n0:n0 + nv].copy(),
                              model.mesh_face[f0:f0 + nf].copy(), model.mesh_facenormal[f0:f0 + nf].copy(),
                              int(model.mesh_vertnum[i]), int(model.mesh_normalnum[i]), int(model.mesh_facenum[i]),
                              int(model.mesh_texcoordadr[i]), int(model.mesh_graphadr[i])))
                model.mesh_vert[v0:v0 + nv] = verts
                model.mesh_normal[n0:n0 + nv] = normals
                model.mesh_face[f0:f0 + nf] = faces
                model.mesh_facenormal[f0:f0 + nf] = faces
                model.mesh_vertnum[i], model.mesh_normalnum[i], model.mesh_facenum[i] = nv, nv, nf
                # No texture coordinates (an untextured material ignores them) and no convex hull (never drawn).
                model.mesh_texcoordadr[i], model.mesh_graphadr[i] = -1, -1
            yield len(saved)
        finally:
            for i, vert, normal, face, facenormal, nv, nn, nf, texadr, graphadr in saved:
                v0, f0, n0 = int(model.mesh_vertadr[i]), int(model.mesh_faceadr[i]), int(model.mesh_normaladr[i])
                model.mesh_vert[v0:v0 + len(vert)] = vert
                model.mesh_normal[n0:n0 + len(normal)] = normal
                model.mesh_face[f0:f0 + len(face)] = face
                model.mesh_facenormal[f0:f0 + len(facenormal)] = facenormal
                model.mesh_vertnum[i], model.mesh_normalnum[i], model.mesh_facenum[i] = nv, nn, nf
                model.mesh_texcoordadr[i], model.mesh_graphadr[i] = texadr, graphadr
