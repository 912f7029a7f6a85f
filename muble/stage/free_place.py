"""Where an object may be put down on the table: the one free-place rule of both worlds.

A footprint is a convex outline on the table plane. The held object keeps its orientation while carried, so the
centres where it would overlap another object form that object's footprint grown by the held one's (a Minkowski
sum), grown again by the gap to keep. A centre is free when it lies outside every such region. The places of a
box are searched on a grid and given nearest a preferred point first.

The rule is the same for the physical and the symbolic world and the tasks' room check; only the footprints
differ. Physics takes them from the bodies' collision geometry in their current pose
(``muble_plugins.primitives.placement``), the symbolic world from the scene graph's bounding boxes laid along the
world axes (``muble.stage.footprint.free_spot``), the room check from the boxes' outlines as the objects stand
(``muble_plugins.common.geometry.room_on_part``).
"""
from __future__ import annotations

import numpy as np

from muble.stage.geometry import hull_2d

PLACE_GAP = 0.015  # m kept between a placed object's footprint and the others'
PLACE_SPACING = 0.01  # m between the places searched

_ANGLES = np.linspace(0.0, 2 * np.pi, 16, endpoint=False)
DISC = np.stack([np.cos(_ANGLES), np.sin(_ANGLES)], axis=1)  # unit circle: round outlines and the gap's growth


def forbidden(obstacle: np.ndarray, held: np.ndarray, gap: float) -> np.ndarray:
    """Half-planes (rows a, b, c with a x + b y + c <= 0 inside) bounding the centres where ``held`` (outline
    points relative to its centre) comes closer than ``gap`` to ``obstacle`` (outline points on the table)."""
    from scipy.spatial import ConvexHull

    grown = (obstacle[:, None, :] - held[None, :, :]).reshape(-1, 2)
    grown = (hull_2d(grown)[:, None, :] + gap * DISC[None]).reshape(-1, 2)
    return ConvexHull(grown).equations


def free_mask(points: np.ndarray, held: np.ndarray, obstacles: list[np.ndarray], gap: float = PLACE_GAP,
              yaw: float = 0.0) -> np.ndarray:
    """Which of the centres ``points`` (n x 2) keep ``gap`` between ``held`` (its outline relative to its centre,
    turned further by ``yaw`` about the vertical) and every outline of ``obstacles``."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if yaw:
        c, s = np.cos(yaw), np.sin(yaw)
        held = held @ np.array([[c, -s], [s, c]]).T
    free = np.ones(len(points), dtype=bool)
    for obstacle in obstacles:
        eq = forbidden(obstacle, held, gap)
        free &= ~np.all(points @ eq[:, :2].T + eq[:, 2] <= 0.0, axis=1)
    return free


def free_places(lo, hi, held: np.ndarray, obstacles: list[np.ndarray], prefer=None, gap: float = PLACE_GAP,
                spacing: float = PLACE_SPACING, yaw: float = 0.0) -> list[np.ndarray]:
    """The free centres (see ``free_mask``) of a ``spacing`` grid over the box ``lo``-``hi``, nearest ``prefer``
    (default: the box's centre) first; ties keep the grid's order, so the answer is deterministic."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    xs = np.arange(lo[0], hi[0] + 1e-9, spacing)
    ys = np.arange(lo[1], hi[1] + 1e-9, spacing)
    if len(xs) == 0 or len(ys) == 0:
        return []
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    points = np.stack([gx.ravel(), gy.ravel()], axis=1)
    chosen = points[free_mask(points, held, obstacles, gap, yaw)]
    prefer = 0.5 * (lo + hi) if prefer is None else np.asarray(prefer, dtype=float)
    return list(chosen[np.argsort(np.linalg.norm(chosen - prefer, axis=1), kind="stable")])
