"""Procedural meshes for household objects: revolved profiles, rounded boxes, handles, and their convex parts.

All meshes are in metres, z up, origin at the centre of the base. Visual meshes come with per-vertex UVs
(``u`` around the object or along x, ``v`` along the profile or along y) so Blender materials can map textures.
Collision geometry is a list of convex parts that follow the real shape: a container wall is cut into angular
sectors × profile bands, each the convex hull of its corner points, so the inside stays hollow.
"""
from __future__ import annotations

import math

import numpy as np
import trimesh

from muble.core.objects import MeshPart

# Bump when any geometry function changes (here or in an object set's models), so cached meshes from older code
# are not reused.
GEOMETRY_VERSION = 7


def _clean(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop zero-area triangles (poles of revolved profiles produce them)."""
    v = vertices[faces]
    area = np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    return vertices, faces[area > 1e-12]


def revolve(profile: np.ndarray, sections: int = 48) -> tuple[MeshPart, np.ndarray]:
    """Revolve an (r, z) polyline about the z axis into a mesh; returns the mesh and its UVs.

    The profile goes from the axis at the bottom, around the cross-section, back to the axis, so the result is
    closed. ``u`` runs around the axis, ``v`` along the profile's arc length.
    """
    profile = np.asarray(profile, dtype=float)
    n = len(profile)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(profile, axis=0), axis=1))])
    v_coord = arc / arc[-1]
    angles = np.linspace(0.0, 2.0 * math.pi, sections + 1)  # seam duplicated for continuous UVs
    r, z = profile[:, 0], profile[:, 1]
    ca, sa = np.cos(angles), np.sin(angles)
    verts = np.stack([np.outer(ca, r), np.outer(sa, r), np.broadcast_to(z, (sections + 1, n))], axis=-1)
    uv = np.stack(np.meshgrid(angles / (2 * math.pi), v_coord, indexing="ij"), axis=-1)
    idx = np.arange((sections + 1) * n).reshape(sections + 1, n)
    a, b = idx[:-1, :-1], idx[1:, :-1]
    c, d = idx[1:, 1:], idx[:-1, 1:]
    # Counter-clockwise seen from outside when the profile runs bottom-outward-up.
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    vertices, faces = _clean(verts.reshape(-1, 3), faces)
    return MeshPart(vertices, faces), uv.reshape(-1, 2)


def hull(points: np.ndarray) -> MeshPart:
    """The convex hull of ``points`` as a mesh part."""
    mesh = trimesh.convex.convex_hull(np.asarray(points, dtype=float))
    return MeshPart(np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64))


def ring_points(r: float, z: float, angles: np.ndarray) -> np.ndarray:
    return np.stack([r * np.cos(angles), r * np.sin(angles), np.full_like(angles, z)], axis=-1)


def disc_part(radius_bottom: float, radius_top: float, z0: float, z1: float, sections: int = 24) -> MeshPart:
    """A convex (truncated) cylinder between heights ``z0`` and ``z1``."""
    angles = np.linspace(0.0, 2 * math.pi, sections, endpoint=False)
    return hull(np.concatenate([ring_points(radius_bottom, z0, angles), ring_points(radius_top, z1, angles)]))


def wall_parts(outer: np.ndarray, inner: np.ndarray, sectors: int = 12) -> list[MeshPart]:
    """Convex pieces of a revolved wall between matching (r, z) outer and inner polylines.

    Band ``i`` spans outer[i..i+1] and inner[i..i+1]; each band is cut into ``sectors`` wedges. The outer
    points are pushed out by the chord sag so that the pieces' outer faces reach the true round surface.
    """
    outer = np.asarray(outer, dtype=float)
    inner = np.asarray(inner, dtype=float)
    sag = 1.0 / math.cos(math.pi / sectors)
    parts = []
    for i in range(len(outer) - 1):
        for s in range(sectors):
            angles = np.array([s, s + 1], dtype=float) * 2 * math.pi / sectors
            pts = [ring_points(outer[j, 0] * sag, outer[j, 1], angles) for j in (i, i + 1)]
            pts += [ring_points(inner[j, 0], inner[j, 1], angles) for j in (i, i + 1)]
            parts.append(hull(np.concatenate(pts)))
    return parts


def container(outer: list[tuple[float, float]], wall: float, base: float, sections: int = 48,
              sectors: int = 12) -> tuple[MeshPart, np.ndarray, list[MeshPart]]:
    """An open revolved vessel (bowl, glass, mug body, plate) from its outer (r, z) profile.

    ``outer`` runs from the base edge (r, 0) up to the rim; the inside is the outer profile moved in by
    ``wall`` with a floor ``base`` thick. Returns visual mesh, UVs and convex collision parts (a floor disc and
    the wall wedges).
    """
    outer = np.asarray(outer, dtype=float)
    inner = outer.copy()
    inner[:, 0] = np.maximum(outer[:, 0] - wall, 1e-3)
    inner[0, 1] = base
    inner[:, 1] = np.maximum(inner[:, 1], base)
    rim_z = outer[-1, 1]
    profile = np.concatenate([[[0.0, 0.0]], outer, [[inner[-1, 0], rim_z]], inner[::-1][1:-1],
                              [[inner[0, 0], base], [0.0, base]]])
    visual, uv = revolve(profile, sections)
    floor = disc_part(outer[0, 0], inner[0, 0] + 0.5 * (outer[0, 0] - inner[0, 0]), 0.0, base, sectors * 2)
    walls = wall_parts(outer, inner, sectors)
    return visual, uv, [floor, *walls]


def rounded_box(size: tuple[float, float, float], radius: float, segments: int = 6) -> tuple[MeshPart, np.ndarray]:
    """A box with rounded vertical edges (x, y full size, z from 0 up); convex, UVs from x and y."""
    sx, sy, sz = size
    radius = min(radius, 0.49 * min(sx, sy))
    corners = [(sx / 2 - radius, sy / 2 - radius), (-sx / 2 + radius, sy / 2 - radius),
               (-sx / 2 + radius, -sy / 2 + radius), (sx / 2 - radius, -sy / 2 + radius)]
    ring = []
    for k, (cx, cy) in enumerate(corners):
        for a in np.linspace(k * math.pi / 2, (k + 1) * math.pi / 2, segments):
            ring.append((cx + radius * math.cos(a), cy + radius * math.sin(a)))
    ring = np.array(ring)
    pts = np.concatenate([np.c_[ring, np.zeros(len(ring))], np.c_[ring, np.full(len(ring), sz)]])
    part = hull(pts)
    uv = np.c_[(part.vertices[:, 0] + sx / 2) / sx, (part.vertices[:, 1] + sy / 2) / sy]
    return part, uv


def tray(size: tuple[float, float, float], wall: float, base: float, flare: float = 0.01
         ) -> tuple[MeshPart, np.ndarray, list[MeshPart]]:
    """A rectangular open tray (baking tray): a floor plate and four slanted walls, each wall one convex part."""
    sx, sy, sz = size
    hx, hy = sx / 2, sy / 2
    bx, by = hx - flare, hy - flare  # the walls lean outwards by ``flare`` from floor to rim
    floor = hull(np.array([[x, y, z] for x in (-bx, bx) for y in (-by, by) for z in (0.0, base)]))

    def slab(x0, x1, y0, y1, xt0, xt1, yt0, yt1):
        bottom = [[x, y, 0.0] for x in (x0, x1) for y in (y0, y1)]
        top = [[x, y, sz] for x in (xt0, xt1) for y in (yt0, yt1)]
        return hull(np.array(bottom + top))

    walls = [
        slab(bx - wall, bx, -by, by, hx - wall, hx, -hy, hy),
        slab(-bx, -bx + wall, -by, by, -hx, -hx + wall, -hy, hy),
        slab(-bx, bx, by - wall, by, -hx, hx, hy - wall, hy),
        slab(-bx, bx, -by, -by + wall, -hx, hx, -hy, -hy + wall),
    ]
    parts = [floor, *walls]
    visual = trimesh.util.concatenate([trimesh.Trimesh(p.vertices, p.faces) for p in parts])
    vertices = np.asarray(visual.vertices, dtype=float)
    uv = np.c_[(vertices[:, 0] + hx) / sx, (vertices[:, 1] + hy) / sy]
    return MeshPart(vertices, np.asarray(visual.faces, dtype=np.int64)), uv, parts


def handle(centre_x: float, z_low: float, z_high: float, reach: float, thickness: float,
           pieces: int = 5) -> list[MeshPart]:
    """A mug handle: a half-ring of tube in the x-z plane from (centre_x, z_low) out by ``reach`` to z_high.

    Each piece is the convex hull of two square tube cross-sections, so the handle is hollow (a finger or
    gripper jaw fits through it).
    """
    zc, rz = 0.5 * (z_low + z_high), 0.5 * (z_high - z_low)
    half = thickness / 2
    parts = []
    angles = np.linspace(-math.pi / 2, math.pi / 2, pieces + 1)
    for a0, a1 in zip(angles[:-1], angles[1:]):
        pts = []
        for a in (a0, a1):
            x, z = centre_x + reach * math.cos(a), zc + rz * math.sin(a)
            nx, nz = math.cos(a), math.sin(a)  # cross-section spans the radial direction and y
            for dr in (-half, half):
                for dy in (-half * 1.4, half * 1.4):
                    pts.append([x + dr * nx, dy, z + dr * nz])
        parts.append(hull(np.array(pts)))
    return parts


def concatenate(parts: list[MeshPart]) -> MeshPart:
    """One mesh holding all ``parts`` (vertices re-indexed)."""
    verts, faces, offset = [], [], 0
    for p in parts:
        verts.append(p.vertices)
        faces.append(p.faces + offset)
        offset += len(p.vertices)
    return MeshPart(np.concatenate(verts), np.concatenate(faces))


def planar_uv(vertices: np.ndarray) -> np.ndarray:
    """Cylindrical UVs (angle around z, normalised height) for meshes without their own."""
    u = (np.arctan2(vertices[:, 1], vertices[:, 0]) / (2 * math.pi)) % 1.0
    z = vertices[:, 2]
    v = (z - z.min()) / max(float(np.ptp(z)), 1e-9)
    return np.c_[u, v]


def mass_properties(parts: list[MeshPart], mass: float) -> tuple[np.ndarray, np.ndarray]:
    """Centre of mass and inertia tensor (about it) of ``parts`` filled uniformly to total ``mass`` (kg).

    The convex parts are the material (walls, floor, handle), so a cup's inertia is that of a shell, not of a
    solid cylinder.
    """
    volumes, centres, inertias = [], [], []
    for p in parts:
        m = trimesh.Trimesh(p.vertices, p.faces, process=True)
        if m.volume < 0:
            m.invert()
        volumes.append(m.volume)
        centres.append(m.center_mass)
        inertias.append(m.moment_inertia)  # about the part's own centre, unit density
    volumes = np.array(volumes)
    density = mass / volumes.sum()
    com = (volumes[:, None] * np.array(centres)).sum(axis=0) / volumes.sum()
    inertia = np.zeros((3, 3))
    for v, c, i in zip(volumes, centres, inertias):
        d = np.asarray(c) - com
        inertia += density * (np.asarray(i) + v * (d @ d * np.eye(3) - np.outer(d, d)))
    return com, 0.5 * (inertia + inertia.T)
