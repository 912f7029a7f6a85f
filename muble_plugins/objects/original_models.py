"""The original SHOP-VRB2 release's 26 object models, rebuilt here from their measured dimensions.

A scene of the original's files (scale factors of 0.6 or less) is built with these shapes, so that what a camera
sees of an object and what the physics collides with match the original's models. The figures are measurements
of the release's visual meshes (``meshes/train/<model>/simple_mesh.stl``, MIT licence) at import scale 1, in
metres: outer radial profiles r(z) of round models, the footprint of flat ones (half widths and corner radius per
height), handle extents and the offset of a body from the model's origin. The geometry itself is this module's
own (lathes, lofts and convex pieces); no mesh of the original is used.

Facts of the original's frame that this module keeps (its ``environment/objects.py`` and ``tabletop_env.py``):
- a model is loaded with its mesh scaled by the scene's ``scale_factor`` and placed with its origin at the
  object's ``3d_coords`` and its ``orientation`` (w, x, y, z) as the free joint's pose; ``rotation`` is the yaw
  of that quaternion in degrees.
- the origin is the middle of the base for round models and the base is at z = 0, except for a few models whose
  mesh reaches below their origin (bowl2 5.5 mm, glass5 3.4 mm, wine_glass2 2.9 mm, wine_glass3 1.7 mm) or
  starts above it (wine_glass1 4.9 mm). The profiles here are in the original's frame, so an object stands at
  the original's height: what lies below the table in the original is hidden in its renders and is cut off
  here (``on_table``), and a foot that floats above it is carried down to the table.
- a handle points along -x (the mugs, thermos2), and a mug's origin is not its body's axis: the body is offset
  by ``centre`` along +x (mug1 15.6 mm). Grasp frames move with the geometry.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from muble.core.objects import GraspFrame, MeshPart
from muble_plugins.objects import geometry as g
from muble_plugins.objects.catalogue import Geometry, side, top_down
from muble_plugins.objects.frames import (GRIP_DEPTH, STEM_GRIP_HEIGHT, cylinder_frames, handle_frames, radius_at,
                                          rim_frames, side_frames)

# The thinnest wall (m at import scale 1) a vessel is built with: the original's glass walls are 1.5-3 mm, which
# at an import scale of 0.45 is thinner than MuJoCo's contacts hold reliably; walls hardly show in a mask.
MIN_WALL = 0.005


# --- building blocks -------------------------------------------------------------------------------------

def _scaled(points, s):
    return [(r * s, z * s) for r, z in points]


def on_table(profile):
    """An (r, z) profile in the original's frame, cut at the table (z = 0) where it reaches below it and carried
    straight down to it where it starts above it."""
    return _on_table(profile, z_index=1)


def levels_on_table(levels):
    """``on_table`` for (z, a, b, c) levels of rounded-rectangle sections."""
    return _on_table(levels, z_index=0)


def _on_table(rows, z_index):
    rows = np.asarray(rows, dtype=float)
    z = rows[:, z_index]
    if z[0] > 0:
        first = rows[0].copy()
        first[z_index] = 0.0
        return np.concatenate([[first], rows]).tolist()
    above = rows[z > 0]
    k = int(np.argmax(z > 0))
    t = (0.0 - z[k - 1]) / (z[k] - z[k - 1])
    cut = rows[k - 1] + t * (rows[k] - rows[k - 1])
    return np.concatenate([[cut], above]).tolist() if z[0] < 0 else rows.tolist()


def lathe(outer, wall: float | None = None, floor: float | None = None, sectors: int = 12,
          sections: int = 48) -> tuple[MeshPart, np.ndarray, list[MeshPart]]:
    """A round body from its outer (r, z) profile (base edge up to the top).

    With ``floor`` the body is a vessel open at the top: solid below ``floor``, and above it a wall ``wall``
    thick (inside = outside moved in). Without, it is solid and closed at the top. Returns the visual mesh, its
    UVs and convex collision parts (discs for the solid bands, wedges for the wall)."""
    outer = np.asarray(outer, dtype=float)
    z0, top = outer[0, 1], outer[-1, 1]
    if floor is None:
        profile = np.concatenate([[[0.0, z0]], outer, [[0.0, top]]])
        visual, uv = g.revolve(profile, sections)
        parts = [g.disc_part(a[0], b[0], a[1], b[1], 2 * sectors) for a, b in zip(outer[:-1], outer[1:])]
        return visual, uv, parts
    r_floor = float(np.interp(floor, outer[:, 1], outer[:, 0]))
    lower = np.concatenate([outer[outer[:, 1] < floor], [[r_floor, floor]]])
    upper = np.concatenate([[[r_floor, floor]], outer[outer[:, 1] > floor]])
    inner = upper.copy()
    inner[:, 0] = np.maximum(upper[:, 0] - wall, 1e-3)
    profile = np.concatenate([[[0.0, z0]], lower, upper[1:], inner[::-1], [[0.0, floor]]])
    visual, uv = g.revolve(profile, sections)
    solid = [g.disc_part(a[0], b[0], a[1], b[1], 2 * sectors) for a, b in zip(lower[:-1], lower[1:])]
    return visual, uv, [*solid, *g.wall_parts(upper, inner, sectors)]


def rounded_rect_ring(a: float, b: float, c: float, z: float, segments: int = 6) -> np.ndarray:
    """Points around a rectangle of half widths ``a``, ``b`` with corners of radius ``c``, at height ``z``:
    ``4 * segments`` of them, counter-clockwise from the +x side, the same count for every size."""
    c = min(c, 0.999 * min(a, b))
    pts = []
    for k, (sx, sy) in enumerate([(1, 1), (-1, 1), (-1, -1), (1, -1)]):
        for t in np.linspace(k * math.pi / 2, (k + 1) * math.pi / 2, segments):
            pts.append((sx * (a - c) + c * math.cos(t), sy * (b - c) + c * math.sin(t), z))
    return np.array(pts)


def loft(levels, wall: float | None = None, floor: float | None = None, pieces: int = 8) -> list[MeshPart]:
    """Convex pieces of a body whose horizontal sections are rounded rectangles (``levels``: (z, a, b, c) from
    the bottom up). Solid without ``wall``; with it, a vessel: a solid floor up to ``floor`` and a wall of
    ``pieces`` pieces around each band above it."""
    rings = [rounded_rect_ring(a, b, c, z) for z, a, b, c in levels]
    if wall is None:
        return [g.hull(np.concatenate([r0, r1])) for r0, r1 in zip(rings[:-1], rings[1:])]
    zs = np.array([lv[0] for lv in levels])

    def level_at(z):
        return [float(np.interp(z, zs, [lv[i] for lv in levels])) for i in (1, 2, 3)]

    parts = [g.hull(np.concatenate([rounded_rect_ring(*level_at(zs[0]), 0.0),
                                    rounded_rect_ring(*level_at(floor), floor)]))]
    upper = [(floor, *level_at(floor))] + [lv for lv in levels if lv[0] > floor]
    outer = [rounded_rect_ring(a, b, c, z) for z, a, b, c in upper]
    inner = [rounded_rect_ring(a - wall, b - wall, max(c - wall, 1e-3), z) for z, a, b, c in upper]
    n = len(outer[0])
    cuts = np.linspace(0, n, pieces + 1).astype(int)
    for i in range(len(upper) - 1):
        for k0, k1 in zip(cuts[:-1], cuts[1:]):
            idx = [j % n for j in range(k0, k1 + 1)]
            pts = [ring[idx] for ring in (outer[i], outer[i + 1], inner[i], inner[i + 1])]
            parts.append(g.hull(np.concatenate(pts)))
    return parts


def strap_handle(path, thickness: float, width: float) -> list[MeshPart]:
    """A handle along ``path`` ((x, z) points of its centre line in the x-z plane), a strap ``thickness`` thick
    in that plane and ``width`` wide along y: one convex piece between consecutive points."""
    path = np.asarray(path, dtype=float)
    parts = []
    for p0, p1 in zip(path[:-1], path[1:]):
        d = (p1 - p0) / max(np.linalg.norm(p1 - p0), 1e-9)
        n = np.array([-d[1], d[0]]) * thickness / 2
        pts = [[x, y, z] for (x, z) in (p0 + n, p0 - n, p1 + n, p1 - n) for y in (-width / 2, width / 2)]
        parts.append(g.hull(np.array(pts)))
    return parts


def handle_path(attach_low, attach_high, reach: float, points: int = 8) -> np.ndarray:
    """The centre line of a mug handle at +x: from ``attach_low`` (x, z) out to ``reach`` (x of its furthest
    point, reached half way up) and back to ``attach_high``: a half ellipse over the line between the attachments."""
    (x0, z0), (x1, z1) = attach_low, attach_high
    t = np.linspace(-math.pi / 2, math.pi / 2, points)
    u = (np.sin(t) + 1) / 2
    base_x = x0 + (x1 - x0) * u
    return np.c_[base_x + (reach - (x0 + x1) / 2) * np.cos(t), z0 + (z1 - z0) * u]


def turned_and_moved(geometry: Geometry, centre=(0.0, 0.0), turn: bool = False) -> Geometry:
    """``geometry`` turned half round about z (``turn``) and then moved by ``centre`` (x, y), with its grasp
    frames."""
    rot = Rotation.from_euler("z", math.pi if turn else 0.0)
    shift = np.array([centre[0], centre[1], 0.0])

    def move(part: MeshPart) -> MeshPart:
        return MeshPart(rot.apply(part.vertices) + shift, part.faces)

    frames = [GraspFrame(rot.apply(f.position) + shift,
                         (rot * Rotation.from_quat(f.quat, scalar_first=True)).as_quat(scalar_first=True), f.width)
              for f in geometry.grasp_frames]
    return Geometry(move(geometry.visual), [move(p) for p in geometry.collision_parts], frames, geometry.uv)


def _convex_body(parts, frames) -> Geometry:
    return Geometry(g.concatenate(parts), parts, frames, None)


# --- model families --------------------------------------------------------------------------------------

def saddle_rim(geometry: Geometry, amplitude: float, z_start: float, z_top: float) -> Geometry:
    """``geometry`` with its rim bent into a saddle: raised by ``amplitude`` over the y axis and lowered by as
    much over the x axis, the bend fading out down to ``z_start`` (a convex part stays convex enough to be
    re-hulled)."""
    def bend(points):
        points = np.array(points, dtype=float)
        theta = np.arctan2(points[:, 1], points[:, 0])
        weight = np.clip((points[:, 2] - z_start) / (z_top - z_start), 0.0, None)
        points[:, 2] += -amplitude * np.cos(2 * theta) * weight
        return points

    frames = [GraspFrame(bend([f.position])[0], f.quat, f.width) for f in geometry.grasp_frames]
    return Geometry(MeshPart(bend(geometry.visual.vertices), geometry.visual.faces),
                    [g.hull(bend(p.vertices)) for p in geometry.collision_parts], frames, geometry.uv)


def bowl(outer, wall, floor, centre=(0.0, 0.0), rim_saddle=None):
    """A bowl; ``rim_saddle`` (amplitude, height where it starts) bends its rim (``saddle_rim``)."""
    outer = on_table(outer)

    def build(s: float) -> Geometry:
        pts, w = _scaled(outer, s), max(wall, MIN_WALL) * s
        visual, uv, parts = lathe(pts, w, floor * s)
        body = Geometry(visual, parts, rim_frames(pts, w, 12), uv)
        if rim_saddle is not None:
            body = saddle_rim(body, rim_saddle[0] * s, rim_saddle[1] * s, pts[-1][1])
        return turned_and_moved(body, _scaled([centre], s)[0])
    return build


def plate(outer, wall, floor):
    outer = on_table(outer)
    def build(s: float) -> Geometry:
        pts = _scaled(outer, s)
        visual, uv, parts = lathe(pts, max(wall, MIN_WALL) * s, floor * s, sectors=16)
        r, h = pts[-1]
        frames = [side((r * math.cos(a), r * math.sin(a), h / 2), a + math.pi, 0.03, closing="vertical")
                  for a in np.arange(4) * math.pi / 2]
        return Geometry(visual, parts, frames, uv)
    return build


def glass(outer, wall, floor):
    outer = on_table(outer)
    def build(s: float) -> Geometry:
        pts, w = _scaled(outer, s), max(wall, MIN_WALL) * s
        visual, uv, parts = lathe(pts, w, floor * s, sectors=10)
        h = pts[-1][1]
        z, mid = h - GRIP_DEPTH, 0.5 * h
        frames = cylinder_frames(radius_at(pts, z), z) + rim_frames(pts, w, 10)
        frames += side_frames(radius_at(pts, max(mid, STEM_GRIP_HEIGHT)), mid)
        return Geometry(visual, parts, frames, uv)
    return build


def square_glass(levels, wall, floor):
    """A tumbler whose section is a rounded square at the base turning round towards the rim (glass5)."""
    levels = levels_on_table(levels)
    def build(s: float) -> Geometry:
        lv = [(z * s, a * s, b * s, c * s) for z, a, b, c in levels]
        parts = loft(lv, max(wall, MIN_WALL) * s, floor * s)
        h, w = lv[-1][0], 2 * lv[-1][1]
        z = h - GRIP_DEPTH
        width_at_z = 2 * float(np.interp(z, [v[0] for v in lv], [v[1] for v in lv]))
        frames = [top_down((0.0, 0.0, z), k * math.pi / 2, width_at_z) for k in range(2)]
        return _convex_body(parts, frames + side_frames(w / 2, 0.5 * h))
    return build


def mug(outer, wall, floor, centre, handle, strap):
    """A mug: a round body whose axis is ``centre`` from the origin, its handle towards -x (``handle``: the
    centre line's lower and upper attachment (r, z) and its reach from the axis; ``strap``: its thickness and
    width)."""
    def build(s: float) -> Geometry:
        pts, w = _scaled(outer, s), max(wall, MIN_WALL) * s
        visual, uv, parts = lathe(pts, w, floor * s, sectors=10)
        low, high, reach = handle
        path = handle_path(_scaled([low], s)[0], _scaled([high], s)[0], reach * s)
        grip = strap_handle(path, strap[0] * s, strap[1] * s)
        r_top, h = pts[-1]
        x_mid = 0.5 * (low[0] + high[0]) * s
        frames = handle_frames(x_mid, low[1] * s, high[1] * s, reach * s - x_mid, strap[1] * s / 1.4, h)
        frames += rim_frames(pts, w, 10, skip=lambda a: abs(math.remainder(a, 2 * math.pi)) < 1.0)
        body = Geometry(g.concatenate([visual, *grip]), [*parts, *grip], frames, None)
        return turned_and_moved(body, _scaled([centre], s)[0], turn=True)
    return build


def can(outer):
    outer = on_table(outer)
    def build(s: float) -> Geometry:
        pts = _scaled(outer, s)
        visual, uv, parts = lathe(pts)
        r = max(p[0] for p in pts)
        h = pts[-1][1]
        frames = cylinder_frames(radius_at(pts, h - GRIP_DEPTH), h - GRIP_DEPTH) + side_frames(r, 0.5 * h)
        return Geometry(visual, parts, frames, uv)
    return build


def flask(outer, handle=None, strap=None):
    """A closed round flask gripped by its top (thermos1), or a jug with a handle towards -x (thermos2)."""
    def build(s: float) -> Geometry:
        pts = _scaled(outer, s)
        visual, uv, parts = lathe(pts)
        h = pts[-1][1]
        r_top = radius_at(pts, h - GRIP_DEPTH)
        frames = cylinder_frames(r_top, h - GRIP_DEPTH) + side_frames(radius_at(pts, 0.5 * h), 0.5 * h)
        if handle is None:
            return Geometry(visual, parts, frames, uv)
        low, high, reach = handle
        grip = strap_handle(handle_path(_scaled([low], s)[0], _scaled([high], s)[0], reach * s),
                            strap[0] * s, strap[1] * s)
        body = Geometry(g.concatenate([visual, *grip]), [*parts, *grip], frames, None)
        return turned_and_moved(body, turn=True)
    return build


def wine_glass(outer, wall, floor):
    """A stemmed glass: one outer profile from the foot's edge along the stem to the rim, the bowl's inside
    from ``floor`` up."""
    outer = on_table(outer)
    def build(s: float) -> Geometry:
        pts, w = _scaled(outer, s), max(wall, MIN_WALL * 0.8) * s
        visual, uv, parts = lathe(pts, w, floor * s, sectors=10)
        bowl_pts = [p for p in pts if p[1] >= floor * s]
        frames = rim_frames(bowl_pts, w, 10)
        stem = [p for p in pts if p[1] < floor * s]
        stem_r = min(r for r, _ in stem)
        stem_z = max(floor * s * 0.5, STEM_GRIP_HEIGHT)
        if stem_z < floor * s - 0.012:
            frames += [side((0.0, 0.0, stem_z), k * math.pi / 4, 2 * stem_r) for k in range(8)]
        return Geometry(visual, parts, frames, uv)
    return build


def round_box(outer, centre):
    """A closed round food container with its lid (food_box2), off the origin by ``centre``."""
    def build(s: float) -> Geometry:
        pts = _scaled(outer, s)
        visual, uv, parts = lathe(pts)
        h = pts[-1][1]
        body = Geometry(visual, parts, cylinder_frames(radius_at(pts, h - 0.02), h - 0.02), uv)
        return turned_and_moved(body, _scaled([centre], s)[0])
    return build


def square_box(levels, centre):
    """A closed box whose sections are rounded squares (food_box1), off the origin by ``centre``."""
    def build(s: float) -> Geometry:
        lv = [(z * s, a * s, b * s, c * s) for z, a, b, c in levels]
        parts = loft(lv)
        h, b_top = lv[-1][0], lv[-1][2]
        body = _convex_body(parts, [top_down((0.0, 0.0, h - 0.02), 0.0, 2 * b_top)])
        return turned_and_moved(body, _scaled([centre], s)[0])
    return build


def sheet_tray(levels, wall, floor):
    """A shallow rectangular tray with flared walls (baking_tray1)."""
    def build(s: float) -> Geometry:
        lv = [(z * s, a * s, b * s, c * s) for z, a, b, c in levels]
        w = max(wall, MIN_WALL) * s
        parts = loft(lv, w, floor * s)
        h, a = lv[-1][0], lv[-1][1]
        frames = [top_down((x, 0.0, h - 0.01), 0.0, w) for x in (a - w / 2, -a + w / 2)]
        return _convex_body(parts, frames)
    return build


def muffin_tray(plate_size, plate_z, cups, cup_r, cup_h):
    """A muffin tray: a flat top plate (half widths, corner radius) at ``plate_z`` (bottom, top) over cups
    widening from ``cup_r[0]`` at the base to ``cup_r[1]`` under the plate, at (x, y) ``cups``."""
    def build(s: float) -> Geometry:
        a, b, c = (v * s for v in plate_size)
        z0, z1 = (v * s for v in plate_z)
        parts = [g.hull(np.concatenate([rounded_rect_ring(a, b, c, z0), rounded_rect_ring(a, b, c, z1)]))]
        for x, y in cups:
            cup = g.disc_part(cup_r[0] * s, cup_r[1] * s, 0.0, cup_h * s, 16)
            parts.append(MeshPart(cup.vertices + [x * s, y * s, 0.0], cup.faces))
        frames = [top_down((x, 0.0, z1 - 0.01), 0.0, z1 - z0) for x in (a - 0.005, -a + 0.005)]
        return _convex_body(parts, frames)
    return build


def board(pieces, thickness):
    """A flat board from rectangles with rounded corners (``pieces``: centre x, centre y, half widths a, b and
    corner radius each) ``thickness`` thick: a slot or a narrower handle is the gap or the narrow piece."""
    def build(s: float) -> Geometry:
        t = thickness * s
        parts = []
        for cx, cy, a, b, c in pieces:
            ring = rounded_rect_ring(a * s, b * s, c * s, 0.0) + [cx * s, cy * s, 0.0]
            parts.append(g.hull(np.concatenate([ring, ring + [0.0, 0.0, t]])))
        visual = g.concatenate(parts)
        y0, y1 = visual.vertices[:, 1].min(), visual.vertices[:, 1].max()
        x = float(np.mean([p[0] for p in pieces[:1]])) * s
        frames = [side((x, y1, t / 2), -math.pi / 2, t, closing="vertical"),
                  side((x, y0, t / 2), math.pi / 2, t, closing="vertical")]
        return _convex_body(parts, frames)
    return build


# --- the measured models (import scale 1, metres) --------------------------------------------------------

ORIGINAL_GEOMETRY: dict[str, Callable[[float], Geometry]] = {
    # A shallow sheet, 348 x 233 mm at the rim, 19 mm deep, walls flaring 12 mm outwards.
    "baking_tray1": sheet_tray([(0.0, 0.1606, 0.1028, 0.010), (0.0031, 0.1626, 0.1044, 0.0113),
                                (0.017, 0.1701, 0.1119, 0.0117), (0.0193, 0.1725, 0.1146, 0.012)], 0.002, 0.003),
    # A 12-cup muffin tray, 300 x 215 mm, cups 24 mm across at the base and 59 mm under the plate.
    "baking_tray2": muffin_tray((0.15, 0.1075, 0.01), (0.0158, 0.0181),
                                [(x, y) for x in (-0.098, -0.0326, 0.0326, 0.098) for y in (-0.0699, 0.0, 0.0699)],
                                (0.0118, 0.0297), 0.0178),
    "bowl1": bowl([(0.039, 0.0), (0.0463, 0.0037), (0.0536, 0.0112), (0.0593, 0.0186), (0.065, 0.0261),
                   (0.0701, 0.0335), (0.074, 0.0409), (0.0769, 0.0484), (0.079, 0.0558), (0.0803, 0.0633),
                   (0.0811, 0.0707), (0.0811, 0.0782), (0.0803, 0.0856), (0.0791, 0.0893)], 0.0045, 0.006),
    # Stands 5.5 mm below its origin in the original; its body is 4.5 mm and 5.1 mm off the origin.
    "bowl2": bowl([(0.0209, -0.0055), (0.0397, -0.0016), (0.0516, 0.0024), (0.0594, 0.0063), (0.0652, 0.0102),
                   (0.0694, 0.0141), (0.075, 0.0219), (0.0782, 0.0298), (0.0809, 0.0376), (0.0824, 0.0455),
                   (0.0836, 0.0533), (0.0842, 0.0611), (0.0846, 0.069), (0.0847, 0.0807), (0.0825, 0.0881)],
                  0.0095, 0.0025, centre=(0.0045, 0.0051)),
    # Its rim is a saddle: 93.3 mm high over the y axis, 85.3 mm over the x axis.
    "bowl3": bowl([(0.0411, 0.0), (0.0442, 0.0034), (0.048, 0.0112), (0.0499, 0.0152), (0.0531, 0.0191),
                   (0.0572, 0.023), (0.061, 0.0269), (0.0647, 0.0308), (0.0679, 0.0347), (0.0707, 0.0387),
                   (0.0736, 0.0426), (0.076, 0.0465), (0.0782, 0.0504), (0.08, 0.0543), (0.0816, 0.0583),
                   (0.0832, 0.0622), (0.084, 0.0661), (0.0848, 0.07), (0.0855, 0.0739), (0.0859, 0.0818),
                   (0.0861, 0.0893)], 0.007, 0.008, rim_saddle=(0.004, 0.045)),
    # A 300 mm square, 21 mm thick.
    "chopping_board1": board([(0.0, 0.0, 0.15, 0.15, 0.028)], 0.0212),
    # 300 x 208 mm, 10 mm thick, a 29 x 112 mm hand slot 116 mm from the middle.
    "chopping_board2": board([(-0.0255, -0.0074, 0.1265, 0.104, 0.0176), (0.1405, -0.0074, 0.0105, 0.104, 0.0176),
                              (0.1155, 0.0713, 0.0146, 0.0252, 0.001),
                              (0.1155, -0.0884, 0.0146, 0.023, 0.001)], 0.0103),
    # A paddle: a 274 x 172 mm blade and a 41 mm wide handle to 421 mm in all, 12.6 mm thick.
    "chopping_board3": board([(-0.0725, 0.0, 0.137, 0.085, 0.02), (0.082, 0.0, 0.02, 0.045, 0.015),
                              (0.155, 0.0, 0.0568, 0.0205, 0.0165)], 0.0126),
    # A rounded-square box widening to its lid seam half way up, 105 mm tall.
    "food_box1": square_box([(0.0, 0.068, 0.068, 0.037), (0.0132, 0.0727, 0.0728, 0.0385),
                             (0.0395, 0.087, 0.087, 0.039), (0.0527, 0.089, 0.089, 0.039),
                             (0.0658, 0.087, 0.087, 0.039), (0.0921, 0.073, 0.073, 0.039),
                             (0.1052, 0.068, 0.068, 0.037)], (0.0, 0.0055)),
    # A round tub, 139 mm across at the base, 157 mm at the top of the body, under a 176 mm lid; 109 mm tall.
    "food_box2": round_box([(0.0697, 0.0), (0.0713, 0.0136), (0.0747, 0.0409), (0.078, 0.0681),
                            (0.0791, 0.0727), (0.0837, 0.0772), (0.0875, 0.0818), (0.088, 0.0863),
                            (0.0878, 0.0908), (0.0852, 0.0954), (0.0826, 0.0999), (0.0807, 0.1045),
                            (0.0807, 0.109)], (-0.0022, 0.0023)),
    "glass1": glass([(0.0383, 0.0), (0.039, 0.0122), (0.0398, 0.0248), (0.0405, 0.0374), (0.0413, 0.0501),
                     (0.042, 0.0627), (0.0428, 0.0753), (0.0436, 0.088), (0.0445, 0.1006), (0.045, 0.1133),
                     (0.0455, 0.1259), (0.0459, 0.1385), (0.0461, 0.1516)], 0.007, 0.015),
    "glass2": glass([(0.0339, 0.0), (0.0389, 0.0077), (0.0375, 0.016), (0.0358, 0.0242), (0.0342, 0.0325),
                     (0.0332, 0.0407), (0.0333, 0.049), (0.0342, 0.0655), (0.0366, 0.082), (0.039, 0.0985),
                     (0.0407, 0.115), (0.041, 0.1315), (0.0416, 0.148), (0.041, 0.1562), (0.0396, 0.1727),
                     (0.0384, 0.1892), (0.0373, 0.198)], 0.005, 0.009),
    "glass3": glass([(0.0163, 0.0), (0.02, 0.0044), (0.0233, 0.0093), (0.0244, 0.0142), (0.0261, 0.0191),
                     (0.0282, 0.029), (0.0299, 0.0388), (0.0318, 0.0486), (0.0329, 0.0585), (0.0326, 0.0683),
                     (0.032, 0.0879), (0.0306, 0.0978), (0.0292, 0.1076), (0.0273, 0.1179)], 0.005, 0.02),
    "glass4": glass([(0.0248, 0.0), (0.0277, 0.0034), (0.0303, 0.0073), (0.0322, 0.0113), (0.0341, 0.0152),
                     (0.0363, 0.0191), (0.0393, 0.0269), (0.0404, 0.0309), (0.0416, 0.0387), (0.0419, 0.0466),
                     (0.0421, 0.0622), (0.0413, 0.074), (0.039, 0.0818), (0.0367, 0.0897), (0.0358, 0.0941)],
                    0.005, 0.022),
    # A tumbler 93 mm tall: a rounded square 86 mm wide at the base (corners of 26 mm) widening and rounding to
    # a 107 mm circle at the rim, on a 65 mm foot 3.4 mm high.
    "glass5": square_glass([(-0.0034, 0.0325, 0.0325, 0.0094), (0.0012, 0.0418, 0.0418, 0.022),
                            (0.0082, 0.0428, 0.0428, 0.0259), (0.0198, 0.0446, 0.0446, 0.0306),
                            (0.0314, 0.0464, 0.0464, 0.0351), (0.043, 0.0482, 0.0482, 0.0394),
                            (0.0546, 0.05, 0.05, 0.0437), (0.0661, 0.0517, 0.0517, 0.048),
                            (0.0777, 0.0535, 0.0535, 0.0522), (0.0847, 0.0546, 0.0546, 0.0546),
                            (0.0893, 0.0532, 0.0532, 0.0532)], 0.0015, 0.008),
    # A straight mug 94 mm across and 116 mm tall, its axis 15.6 mm along +x from the origin; a strap handle
    # (8 x 18 mm) from 30 to 91 mm up reaching 82 mm from the axis.
    "mug1": mug([(0.047, 0.0), (0.047, 0.1161)], 0.006, 0.005, (0.0156, -0.0011),
                ((0.0455, 0.030), (0.0455, 0.091), 0.082), (0.0078, 0.0178)),
    "mug2": mug([(0.0312, 0.0), (0.0338, 0.0045), (0.0359, 0.0095), (0.0374, 0.0145), (0.039, 0.0195),
                 (0.0406, 0.0244), (0.0417, 0.0294), (0.043, 0.0344), (0.0442, 0.0444), (0.0452, 0.0544),
                 (0.0464, 0.0644), (0.0476, 0.0743), (0.048, 0.0843), (0.0481, 0.1043), (0.0483, 0.1198)],
                0.004, 0.006, (0.0242, 0.0), ((0.0365, 0.027), (0.0465, 0.096), 0.0835), (0.0083, 0.0163)),
    "mug3": mug([(0.0503, 0.0), (0.0531, 0.0045), (0.0532, 0.0095), (0.0518, 0.0195), (0.0505, 0.0296),
                 (0.0498, 0.0396), (0.0495, 0.0546), (0.0492, 0.0746), (0.0493, 0.0896), (0.0503, 0.0996),
                 (0.0516, 0.1097), (0.0523, 0.1147), (0.0512, 0.1201)],
                0.007, 0.02, (0.0211, 0.0), ((0.048, 0.040), (0.049, 0.097), 0.0885), (0.0095, 0.0175)),
    "plate1": plate([(0.0804, 0.0), (0.0821, 0.0016), (0.0818, 0.0056), (0.0834, 0.0066), (0.0883, 0.0076),
                     (0.0974, 0.0096), (0.1028, 0.0117), (0.1071, 0.0137), (0.1105, 0.0157), (0.1138, 0.0177),
                     (0.1172, 0.0197), (0.1206, 0.0217), (0.1224, 0.0241)], 0.003, 0.008),
    "plate2": plate([(0.0959, 0.0), (0.098, 0.0002), (0.1005, 0.0009), (0.1037, 0.0023), (0.1069, 0.0037),
                     (0.1101, 0.0051), (0.1133, 0.0066), (0.1166, 0.008), (0.1197, 0.0094), (0.1229, 0.0108),
                     (0.1258, 0.0123), (0.1284, 0.0137), (0.1309, 0.0151), (0.1317, 0.0171)], 0.006, 0.003),
    "soda_can": can([(0.0305, 0.0), (0.0344, 0.0052), (0.0396, 0.011), (0.0397, 0.0168), (0.0396, 0.1205),
                     (0.0366, 0.1263), (0.0337, 0.132), (0.0335, 0.1383)]),
    "thermos1": flask([(0.0349, 0.0), (0.0367, 0.0097), (0.0369, 0.02), (0.0366, 0.22), (0.0363, 0.2245),
                       (0.0321, 0.2343), (0.0225, 0.2449)]),
    # A jug with a lid and a handle (8.5 x 15.5 mm) from 77 to 156 mm up reaching 68 mm from the axis.
    "thermos2": flask([(0.0353, 0.0), (0.0359, 0.0141), (0.0369, 0.0288), (0.0378, 0.0434), (0.0387, 0.058),
                       (0.0396, 0.0726), (0.0401, 0.0872), (0.0404, 0.1091), (0.0408, 0.1384), (0.0407, 0.1457),
                       (0.0434, 0.153), (0.0419, 0.1603), (0.0416, 0.1676), (0.0419, 0.1754)],
                      ((0.038, 0.077), (0.040, 0.156), 0.068), (0.0085, 0.0155)),
    # Foot, stem and bowl as one profile; the originals start 4.9 mm above (wine_glass1) or reach 2.9 and
    # 1.7 mm below their origins, built here from z = 0.
    "wine_glass1": wine_glass([(0.0293, 0.0049), (0.028, 0.0079), (0.0119, 0.0128), (0.0063, 0.0208),
                               (0.0054, 0.0287), (0.005, 0.0367), (0.0051, 0.0446), (0.0055, 0.0605),
                               (0.0061, 0.0685), (0.0074, 0.0764), (0.0095, 0.0844), (0.013, 0.0923),
                               (0.0185, 0.1003), (0.0248, 0.1082), (0.0297, 0.1162), (0.0328, 0.1241),
                               (0.034, 0.1321), (0.0338, 0.14), (0.0328, 0.1559), (0.0303, 0.1718),
                               (0.0273, 0.1877), (0.0256, 0.1957)], 0.005, 0.0999),
    "wine_glass2": wine_glass([(0.0211, -0.0029), (0.02, 0.0001), (0.0072, 0.0061), (0.0043, 0.0151), (0.0038, 0.0241),
                               (0.0036, 0.0332), (0.0034, 0.0422), (0.0035, 0.0512), (0.0038, 0.0603),
                               (0.0044, 0.0693), (0.0052, 0.0783), (0.0068, 0.0874), (0.0091, 0.0964),
                               (0.013, 0.1054), (0.0176, 0.1144), (0.0211, 0.1235), (0.0233, 0.1325),
                               (0.0242, 0.1415), (0.0243, 0.1506), (0.0235, 0.1686), (0.0217, 0.1867),
                               (0.0196, 0.2047), (0.0185, 0.2138)], 0.004, 0.1071),
    "wine_glass3": wine_glass([(0.0332, -0.0017), (0.0226, 0.006), (0.0085, 0.0137), (0.0052, 0.0214),
                               (0.005, 0.0291), (0.0048, 0.0445), (0.0048, 0.0599), (0.0047, 0.0676),
                               (0.0056, 0.0753), (0.011, 0.083), (0.0207, 0.0907), (0.0286, 0.0984),
                               (0.0352, 0.1061), (0.0379, 0.1138), (0.0393, 0.1215), (0.0393, 0.1292),
                               (0.0378, 0.1446), (0.034, 0.16), (0.0299, 0.1754), (0.0278, 0.1831)], 0.005, 0.0903),
}
