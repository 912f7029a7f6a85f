"""Simplified visual meshes for small images: the model's detailed meshes drawn from coarser copies.

A robosuite Panda's visual meshes hold some 170k triangles, most of them far smaller than a pixel of a 128x128
image; on a software rasteriser drawing them is most of such a frame. Each detailed mesh is drawn from a copy
made by quadric edge-collapse decimation (``fast_simplification``, the Fast Quadric Mesh Simplification
algorithm) at the strongest of a few reductions (97 % of the triangles removed down to 40 %) whose surface stays
within a tolerance of every vertex of the mesh as modelled. The tolerance, not a fixed share, decides each mesh
(within 5 mm the Panda's parts lose 40 to 97 % of their triangles, the Robotiq's fingers 80 %): a fixed share
erodes thin parts such as a gripper's linkage, which is what hides the objects it handles. With a tolerance under
a pixel's footprint the silhouettes, and so the masks, stay where they were (benchmarks/gym_speed.py measures the
masks' IoU against the meshes as modelled).

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
# Shares of a mesh's triangles removed, tried from the strongest until one keeps within the tolerance.
REDUCTIONS = (0.97, 0.95, 0.9, 0.8, 0.6, 0.4)
# Vertices closer than this are one vertex for the decimation (meshes are stored with a vertex per normal).
WELD = 1e-7
# Candidate triangles per point when measuring a vertex's distance to a simplified surface.
NEAREST_TRIANGLES = 16


def weld(verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(verts, faces)`` with coincident vertices merged, so that the decimation sees one connected surface
    (a mesh stored with a vertex per normal is otherwise a heap of separate triangles to it)."""
    verts = np.asarray(verts, dtype=np.float64)
    _, first, index = np.unique(np.round(verts / WELD).astype(np.int64), axis=0, return_index=True,
                                return_inverse=True)
    return verts[first], index.ravel()[np.asarray(faces)].astype(np.int32)


def deviation(points: np.ndarray, verts: np.ndarray, faces: np.ndarray) -> float:
    """The largest distance from ``points`` to the surface ``(verts, faces)``, each point measured against its
    nearest triangles by centroid (an upper bound of the true distance: a nearer triangle missed only makes the
    figure larger)."""
    from scipy.spatial import cKDTree
    from trimesh.triangles import closest_point

    triangles = np.asarray(verts, dtype=np.float64)[np.asarray(faces)]
    k = min(NEAREST_TRIANGLES, len(triangles))
    _, nearest = cKDTree(triangles.mean(axis=1)).query(points, k=k)
    nearest = np.asarray(nearest).reshape(len(points), k)
    repeated = np.repeat(points, k, axis=0)
    gaps = np.linalg.norm(closest_point(triangles[nearest.ravel()], repeated) - repeated, axis=1)
    return float(gaps.reshape(len(points), k).min(axis=1).max())


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit area-weighted vertex normals of a triangle mesh."""
    face_normals = np.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]])
    normals = np.zeros_like(verts)
    for corner in range(3):
        np.add.at(normals, faces[:, corner], face_normals)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)


def decimate(verts: np.ndarray, faces: np.ndarray,
             tolerance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float] | None:
    """``(verts, faces, normals, reduction)`` of the mesh decimated at the strongest of ``REDUCTIONS`` whose
    surface lies within ``tolerance`` metres of every vertex of the mesh as given; None when none does."""
    import fast_simplification

    welded, welded_faces = weld(verts, faces)
    for reduction in REDUCTIONS:
        out_verts, out_faces = fast_simplification.simplify(welded, welded_faces, target_reduction=reduction)
        if len(out_faces) and deviation(welded, out_verts, out_faces) <= tolerance:
            out_faces = np.asarray(out_faces, dtype=np.int32)
            return out_verts, out_faces, vertex_normals(out_verts, out_faces), reduction
    return None


def _textured_meshes(model) -> set[int]:
    """Meshes drawn with a textured material: their texture coordinates must stay, so they are not simplified."""
    import mujoco

    textured = set()
    for g in np.flatnonzero((model.geom_type == mujoco.mjtGeom.mjGEOM_MESH) & (model.geom_dataid >= 0)):
        mat = int(model.geom_matid[g])
        if mat >= 0 and (np.asarray(model.mat_texid[mat]) >= 0).any():
            textured.add(int(model.geom_dataid[g]))
    return textured


# Decimated copies by (tolerance, mesh content), for the process: every renderer and every new model of the same
# robot (every scene builds one) reuses them (the Panda's take about 2 s to make).
_DECIMATED: dict[tuple[float, bytes], tuple[np.ndarray, np.ndarray, np.ndarray] | None] = {}


class SimplifiedMeshes:
    """Decimated copies of a model's detailed meshes within ``tolerance`` metres, kept by content."""

    def __init__(self, tolerance: float):
        self.tolerance = float(tolerance)
        self._cache = _DECIMATED

    def _simplified(self, model, i: int):
        v0, nv = int(model.mesh_vertadr[i]), int(model.mesh_vertnum[i])
        f0, nf = int(model.mesh_faceadr[i]), int(model.mesh_facenum[i])
        verts, faces = model.mesh_vert[v0:v0 + nv], model.mesh_face[f0:f0 + nf]
        key = (self.tolerance, hashlib.blake2b(verts.tobytes() + faces.tobytes(), digest_size=16).digest())
        if key not in self._cache:
            out = decimate(verts, faces, self.tolerance)
            # Kept only if it saves something and fits the mesh's own slots (the arrays cannot grow).
            fits = out is not None and 0 < len(out[1]) < nf and len(out[0]) <= min(nv, int(model.mesh_normalnum[i]))
            self._cache[key] = out[:3] if fits else None
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
