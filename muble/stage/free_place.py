"""Where an object may be put down on the table: the one free-place rule of both worlds.

A footprint is a convex outline on the table plane. The held object keeps its orientation while carried, so the
centres where it would overlap another object form that object's footprint grown by the held one's (a Minkowski
sum), grown again by the gap to keep. A centre is free when it lies outside every such region. The places of a
box are searched on a grid and given nearest a preferred point first.

The rule is the same for the physical and the symbolic world and the tasks' room check; only the footprints
differ. Physics takes them from the bodies' collision geometry in their current pose
(``muble_plugins.primitives.placement``), the symbolic world from the scene graph's bounding boxes laid along the
world axes (``muble.stage.footprint.free_spot``), the room check from the boxes' outlines as the objects stand
(``muble_plugins.common.geometry.room_on_part``). The room check asks only for the nearest place or whether there
is one, thousands of times a split: ``first_free_place`` and ``has_free_place`` give ``free_places``' answers to
the bit, building the forbidden regions (and the outlines, given as ``Footprint``s) only where they decide them.
"""
from __future__ import annotations

import functools
from typing import Callable, NamedTuple

import numpy as np

from muble.stage.geometry import hull_2d

PLACE_GAP = 0.015  # m kept between a placed object's footprint and the others'
PLACE_SPACING = 0.01  # m between the places searched
# How far (m) beyond the support of an obstacle's forbidden region a centre lies to count as surely outside it
# (``first_free_place``). The region is a convex polygon grown by a 16-gon, so its edges turn by at most 22.5
# degrees at a corner: a centre this far outside it lies at least 0.98 of this outside one of its half-planes,
# far beyond the rounding (1e-15 m) of the half-planes the hull is computed as.
_SURELY_OUT = 1e-6

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
    held = _turned(held, yaw)
    free = np.ones(len(points), dtype=bool)
    for obstacle in obstacles:
        free &= ~_inside(points, forbidden(obstacle, held, gap))
    return free


def _turned(held: np.ndarray, yaw: float) -> np.ndarray:
    """``held`` turned by ``yaw`` about its centre (itself when ``yaw`` is 0)."""
    if yaw:
        c, s = np.cos(yaw), np.sin(yaw)
        held = held @ np.array([[c, -s], [s, c]]).T
    return held


def _inside(points: np.ndarray, eq: np.ndarray) -> np.ndarray:
    """Which of ``points`` lie inside the half-planes ``eq`` (``forbidden``). Always evaluated over the whole set
    of centres asked about: a product over fewer rows may take another BLAS kernel and round differently."""
    return np.all(points @ eq[:, :2].T + eq[:, 2] <= 0.0, axis=1)


def free_places(lo, hi, held: np.ndarray, obstacles: list[np.ndarray], prefer=None, gap: float = PLACE_GAP,
                spacing: float = PLACE_SPACING, yaw: float = 0.0) -> list[np.ndarray]:
    """The free centres (see ``free_mask``) of a ``spacing`` grid over the box ``lo``-``hi``, nearest ``prefer``
    (default: the box's centre) first; ties keep the grid's order, so the answer is deterministic."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    points = _grid(lo, hi, spacing)
    if len(points) == 0:
        return []
    chosen = points[free_mask(points, held, obstacles, gap, yaw)]
    prefer = 0.5 * (lo + hi) if prefer is None else np.asarray(prefer, dtype=float)
    return list(chosen[np.argsort(np.linalg.norm(chosen - prefer, axis=1), kind="stable")])


class Footprint:
    """An outline on the table plane that a search builds only where it needs it exactly (``first_free_place``,
    ``has_free_place``).

    ``around``: points whose convex hull holds the outline (a box's corners seen from above, or the outline
    itself), enough to rule out the centres far from it. ``build``: makes the outline (a convex hull), at most once.
    """

    __slots__ = ("around", "_build", "_outline")

    def __init__(self, around: np.ndarray, build: Callable[[], np.ndarray]):
        self.around = around
        self._build = build
        self._outline: np.ndarray | None = None

    @property
    def outline(self) -> np.ndarray:
        if self._outline is None:
            self._outline = self._build()
        return self._outline

    def shifted(self, offset: np.ndarray) -> "Footprint":
        """This footprint moved by ``offset``: its outline is this one's outline plus ``offset``."""
        return Footprint(self.around + offset, lambda: self.outline + offset)


Shape = np.ndarray | Footprint  # an outline, or a footprint that builds it when needed


def first_free_place(lo, hi, held: Shape, obstacles: list[Shape], prefer=None, gap: float = PLACE_GAP,
                     spacing: float = PLACE_SPACING, yaw: float = 0.0) -> np.ndarray | None:
    """``free_places(...)[0]``, the same centre to the bit, or None where the box has no free centre; for callers
    that need only the nearest place (the tasks' room check asks thousands of times per split). The outlines may be
    ``Footprint``s, built only where the answer depends on them.

    Building an obstacle's forbidden region costs two convex hulls, far more than the rest of the search, so a
    region is built only where it can decide the answer. The region is bounded by the 16 half-planes of its
    support along ``DISC``'s directions (the obstacle's support grown by the held outline's and the gap, plus
    ``_SURELY_OUT``), which cost a product of a few points each: a centre outside one of them is surely outside
    the region. Walking the centres nearest ``prefer`` first, the next centre free of the regions built so far is
    the answer unless a region not built may hold it; only such regions are built, each tested exactly as
    ``free_mask`` does, over the whole grid."""
    return _search(lo, hi, held, obstacles, prefer, gap, spacing, yaw, nearest=True)


def has_free_place(lo, hi, held: Shape, obstacles: list[Shape], gap: float = PLACE_GAP,
                   spacing: float = PLACE_SPACING, yaw: float = 0.0) -> bool:
    """Whether ``free_places`` finds any place, the same answer. A centre outside every region's box along x and
    y, else outside every region's 16 half-planes (see ``first_free_place``), answers with no region built; only
    where there is none are the regions built, one by one, until a centre is free."""
    return _search(lo, hi, held, obstacles, None, gap, spacing, yaw, nearest=False) is not None


def _search(lo, hi, held: Shape, obstacles: list[Shape], prefer, gap: float, spacing: float, yaw: float,
            nearest: bool) -> np.ndarray | None:
    """The first free centre nearest ``prefer`` (``nearest``), or any free centre; None where there is none."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    prefer = 0.5 * (lo + hi) if prefer is None else np.asarray(prefer, dtype=float)
    grid = _sorted_grid(tuple(lo.tolist()), tuple(hi.tolist()), float(spacing), tuple(prefer.tolist()))
    points, order, along = grid.points, grid.order, grid.along
    if len(points) == 0:
        return None
    if not obstacles:
        return points[order[0]]
    around = [_around(o) for o in obstacles]
    starts = np.cumsum([0] + [len(a) for a in around[:-1]])
    every, held_around = np.concatenate(around), _turned(_around(held), yaw)
    if not nearest:
        # Any centre outside every region's box (along x and y: a few comparisons per obstacle) is the answer.
        low = np.minimum.reduceat(every, starts, axis=0) - held_around.max(axis=0) - (gap + _SURELY_OUT)
        high = np.maximum.reduceat(every, starts, axis=0) - held_around.min(axis=0) + (gap + _SURELY_OUT)
        in_x = (grid.xs >= low[:, :1]) & (grid.xs <= high[:, :1])
        in_y = (grid.ys >= low[:, 1:]) & (grid.ys <= high[:, 1:])
        outside = np.flatnonzero(~(in_x[:, :, None] & in_y[:, None, :]).any(axis=0).ravel())
        if len(outside):
            return points[outside[0]]
    # bounds[k, j]: how far along DISC[j] obstacle k's region reaches at most (its points', grown).
    reach = gap + _SURELY_OUT - (held_around @ DISC.T).min(axis=0)
    bounds = np.maximum.reduceat(every @ DISC.T, starts, axis=0) + reach
    built = np.zeros(len(obstacles), dtype=bool)
    state: dict[str, np.ndarray] = {}  # the held outline (turned) and the free centres, once a region is built

    def build(k: int) -> np.ndarray:
        if not state:
            state["held"], state["free"] = _turned(_outline(held), yaw), np.ones(len(points), dtype=bool)
        state["free"] &= ~_inside(points, forbidden(_outline(obstacles[k]), state["held"], gap))
        built[k] = True
        return state["free"]

    if not nearest:
        # Any free centre will do: one surely outside every region, else (the regions built one by one) one free
        # of the built regions and surely outside the others.
        maybe = ~(along[:, None, :] > bounds).any(axis=2)  # maybe[i, k]: in ``order``
        clear = np.flatnonzero(~maybe.any(axis=1))
        if len(clear):
            return points[order[clear[0]]]
        for k in np.flatnonzero(maybe.any(axis=0)):
            free = build(int(k))
            hit = np.flatnonzero(free[order] & ~maybe[:, ~built].any(axis=1))
            if len(hit):
                return points[order[hit[0]]]
        return None
    # Nearest first: every centre before ``at`` (in ``order``) is blocked by a built region. The next centre free of
    # the built regions is the answer unless an unbuilt region may hold it; then those are built, and so on.
    at = 0
    while True:
        if state:
            later = np.flatnonzero(state["free"][order[at:]])
            if not len(later):
                return None
            at += int(later[0])
        maybe = ~built & ~(along[at] > bounds).any(axis=1)
        if not maybe.any():
            return points[order[at]]
        for k in np.flatnonzero(maybe):
            build(int(k))


def _around(shape: Shape) -> np.ndarray:
    return shape.around if isinstance(shape, Footprint) else shape


def _outline(shape: Shape) -> np.ndarray:
    return shape.outline if isinstance(shape, Footprint) else shape


class _Grid(NamedTuple):
    points: np.ndarray  # the centres (n x 2), x major
    xs: np.ndarray  # their x values, then y values: points[i * len(ys) + j] is (xs[i], ys[j])
    ys: np.ndarray
    order: np.ndarray  # the centres nearest the preferred point first
    along: np.ndarray  # the ordered centres' coordinates along ``DISC``'s directions


@functools.lru_cache(maxsize=64)
def _sorted_grid(lo: tuple[float, float], hi: tuple[float, float], spacing: float,
                 prefer: tuple[float, float]) -> _Grid:
    """The grid of ``free_places`` over ``lo``-``hi``, nearest ``prefer`` first; read-only, shared between calls
    (a room check searches the same few table parts all the time)."""
    xs, ys = _axes(np.asarray(lo), np.asarray(hi), spacing)
    points = _grid(np.asarray(lo), np.asarray(hi), spacing)
    # The same norms, row by row, as ``free_places`` sorts its free subset by; a stable sort of all centres keeps
    # ties in grid order, so the first free centre in this order is its first place.
    order = np.argsort(np.linalg.norm(points - np.asarray(prefer), axis=1), kind="stable")
    grid = _Grid(points, xs, ys, order, points[order] @ DISC.T)
    for array in grid:
        array.flags.writeable = False
    return grid


def _axes(lo: np.ndarray, hi: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    return np.arange(lo[0], hi[0] + 1e-9, spacing), np.arange(lo[1], hi[1] + 1e-9, spacing)


def _grid(lo: np.ndarray, hi: np.ndarray, spacing: float) -> np.ndarray:
    """The centres (n x 2) of a ``spacing`` grid over the box ``lo``-``hi``, x major; none where it is empty."""
    xs, ys = _axes(lo, hi, spacing)
    if len(xs) == 0 or len(ys) == 0:
        return np.zeros((0, 2))
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    return np.stack([gx.ravel(), gy.ravel()], axis=1)
