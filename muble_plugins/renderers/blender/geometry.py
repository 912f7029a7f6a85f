"""Triangle meshes of MuJoCo geoms, in the geom's own frame, ready to become Blender meshes.

MuJoCo stores compiled mesh assets already expressed in their geom's frame, so a geom's world transform
(``geom_xpos``, ``geom_xmat``) places them directly. Primitives are tessellated here from ``geom_size``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from muble.core.errors import RenderError

if TYPE_CHECKING:  # pragma: no cover
    import mujoco

# mjtGeom values (stable in MuJoCo 3).
PLANE, HFIELD, SPHERE, CAPSULE, ELLIPSOID, CYLINDER, BOX, MESH = 0, 1, 2, 3, 4, 5, 6, 7
GEOM_TYPE_NAMES = {PLANE: "plane", SPHERE: "sphere", CAPSULE: "capsule", ELLIPSOID: "ellipsoid",
                   CYLINDER: "cylinder", BOX: "box", MESH: "mesh"}
INFINITE_PLANE_HALF_SIZE = 10.0  # metres: MuJoCo planes of size 0 are infinite
SECTIONS = 48  # round primitives: segments around the axis, enough for smooth silhouettes at 640 px


@dataclass
class GeomMesh:
    vertices: np.ndarray  # (V, 3) float
    faces: np.ndarray  # (F, 3) int
    smooth: bool  # shade smooth (curved surfaces) or flat (boxes, planes)


def geom_mesh(model: "mujoco.MjModel", geom: int) -> GeomMesh:
    """The mesh of one geom in its own frame; raises ``RenderError`` for types that cannot be drawn."""
    import trimesh.creation as creation

    kind = int(model.geom_type[geom])
    size = np.asarray(model.geom_size[geom], dtype=float)
    if kind == MESH:
        mesh_id = int(model.geom_dataid[geom])
        v0, nv = model.mesh_vertadr[mesh_id], model.mesh_vertnum[mesh_id]
        f0, nf = model.mesh_faceadr[mesh_id], model.mesh_facenum[mesh_id]
        return GeomMesh(np.array(model.mesh_vert[v0:v0 + nv], dtype=float),
                        np.array(model.mesh_face[f0:f0 + nf], dtype=np.int64), smooth=True)
    if kind == BOX:
        box = creation.box(extents=2 * size)
        return GeomMesh(box.vertices, box.faces, smooth=False)
    if kind == PLANE:
        hx = size[0] if size[0] > 0 else INFINITE_PLANE_HALF_SIZE
        hy = size[1] if size[1] > 0 else INFINITE_PLANE_HALF_SIZE
        vertices = np.array([[-hx, -hy, 0], [hx, -hy, 0], [hx, hy, 0], [-hx, hy, 0]], dtype=float)
        return GeomMesh(vertices, np.array([[0, 1, 2], [0, 2, 3]]), smooth=False)
    if kind == SPHERE:
        sphere = creation.uv_sphere(radius=size[0], count=[SECTIONS // 2, SECTIONS])
        return GeomMesh(sphere.vertices, sphere.faces, smooth=True)
    if kind == ELLIPSOID:
        sphere = creation.uv_sphere(radius=1.0, count=[SECTIONS // 2, SECTIONS])
        return GeomMesh(sphere.vertices * size[:3], sphere.faces, smooth=True)
    if kind == CYLINDER:
        cylinder = creation.cylinder(radius=size[0], height=2 * size[1], sections=SECTIONS)
        return GeomMesh(cylinder.vertices, cylinder.faces, smooth=False)
    if kind == CAPSULE:
        capsule = creation.capsule(height=2 * size[1], radius=size[0], count=[SECTIONS, SECTIONS // 2])
        return GeomMesh(capsule.vertices, capsule.faces, smooth=True)
    raise RenderError(f"geom {geom} has type {kind}, which the Blender renderer cannot draw; "
                      f"drawable types: {', '.join(GEOM_TYPE_NAMES.values())}")


def geom_rgba(model: "mujoco.MjModel", geom: int) -> np.ndarray:
    """The colour MuJoCo draws a geom with: its material's colour when it has one, else its own rgba."""
    mat = int(model.geom_matid[geom])
    if mat >= 0:
        # MuJoCo uses the material colour unless the geom overrides the default grey.
        default = np.array([0.5, 0.5, 0.5, 1.0], dtype=np.float32)
        if np.allclose(model.geom_rgba[geom], default):
            return np.array(model.mat_rgba[mat], dtype=float)
    return np.array(model.geom_rgba[geom], dtype=float)
