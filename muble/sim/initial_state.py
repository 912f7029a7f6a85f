"""The initial-state check: before an agent acts, the scene is settled and every object must be found at rest.

``settle_and_check(env)`` runs on a freshly reset ``TabletopEnv``:

1. before any physics, each object must have a plausible mass (``MASS_RANGE_G``), its centre of mass over the
   table top, no contact deeper than ``MAX_PENETRATION`` with the table, the robot or another object, and a support
   (the table or another object) within ``SUPPORT_GAP``;
2. the physics then runs for ``SETTLE_TIME`` with the arm holding its rest pose and the gripper open;
3. afterwards every object must have settled (``muble.stage.rest.settled``: moved at most ``SETTLED_DISPLACEMENT``,
   its origin or its centre of mass, and turned at most ``SETTLED_TURN``), sunk no deeper than ``MAX_PENETRATION``
   into anything, and touch a support.

The first failure raises ``InitialStateError`` naming the object and the check; the episode is then a broken scene
(the data's fault) and the agent never acts. On success the environment is left settled, its step counter where
it was, and a ``InitialStateReport`` says how far each object moved. Tolerances and the figures they were measured
against are in docs/environment.md ("Initial state").
"""
from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from muble.core.errors import InitialStateError, PhysicsError
from muble.sim.world import TABLE_GEOM
from muble.stage.geometry import turn_deg
from muble.stage.rest import SETTLED_DISPLACEMENT, SETTLED_TURN, settled
from muble.stage.table import BELOW_TABLE

SETTLE_TIME = 0.5  # s of physics before the check: a 5 cm drop lands in 0.1 s, a tipping object is well under way
MAX_PENETRATION = 0.003  # m of contact depth (before and after settling); resting contacts are ~0.2 mm deep
SUPPORT_GAP = 0.002  # m between an object and its support that still counts as resting on it
FLOATING_SEARCH = 0.2  # m: how far below an unsupported object its support is looked for, to say how high it floats
MASS_RANGE_G = (1.0, 10_000.0)  # g: a tabletop household object the arm works with weighs between these


@dataclass
class ObjectRest:
    """How one object settled: displacement of origin or centre of mass (m), rotation (degrees), the deepest
    contact after settling (m) and what it rests on (``"table"`` or an object id)."""

    id: int
    displacement: float
    rotation: float
    penetration: float
    support: int | str | None


@dataclass
class InitialStateReport:
    """The outcome of a passed check: the settle time (s) and how each object settled."""

    settle_time: float
    objects: dict[int, ObjectRest] = field(default_factory=dict)

    @property
    def max_displacement(self) -> float:
        return max((o.displacement for o in self.objects.values()), default=0.0)

    @property
    def max_rotation(self) -> float:
        return max((o.rotation for o in self.objects.values()), default=0.0)

    @property
    def max_penetration(self) -> float:
        return max((o.penetration for o in self.objects.values()), default=0.0)


class _Parties:
    """What each geom of the world is, in the words of an error message: an object id, "table" or "robot"."""

    def __init__(self, env):
        m = env.model
        self.model = m
        self.geom_object = env.grasp.geom_object  # geom -> scene id, -1 for anything else
        self.table = m.geom(TABLE_GEOM).id
        prefixes = tuple(env.names.robot_geom_prefixes)
        self.robot = np.array([bool(prefixes) and (m.geom(g).name or "").startswith(prefixes)
                               for g in range(m.ngeom)])
        # Collision geoms of each object (its visual geom collides with nothing).
        self.collision = {i: [g for g in np.flatnonzero(self.geom_object == i) if m.geom_contype[g] or
                              m.geom_conaffinity[g]] for i in env.grasp.body_of}

    def name(self, geom: int) -> int | str:
        obj = int(self.geom_object[geom])
        if obj >= 0:
            return obj
        if geom == self.table:
            return "table"
        if self.robot[geom]:
            return "robot"
        body = self.model.geom_bodyid[geom]
        return self.model.geom(geom).name or self.model.body(body).name or f"geom {geom}"

    def is_support(self, geom: int, obj: int) -> bool:
        other = int(self.geom_object[geom])
        return geom == self.table or (other >= 0 and other != obj)


def _describe(party: int | str) -> str:
    return f"object {party}" if isinstance(party, int) else f"the {party}"


def check_masses(env) -> None:
    """Raise ``InitialStateError`` for an object whose simulated mass is outside ``MASS_RANGE_G``."""
    low, high = MASS_RANGE_G
    for obj, body in env.grasp.body_of.items():
        grams = float(env.model.body_mass[body]) * 1000.0
        if not (low <= grams <= high):
            raise InitialStateError(
                f"weighs {grams:.6g} g, outside the plausible range for a tabletop object ({low:g}-{high:g} g); "
                "fix its weight_gt in the scene", obj=obj, check="mass")


def check_over_table(env) -> None:
    """Raise ``InitialStateError`` for an object whose centre of mass is not over the table top."""
    m, d = env.model, env.data
    table = m.geom(TABLE_GEOM).id
    centre, half = d.geom_xpos[table], m.geom_size[table]
    for obj, body in env.grasp.body_of.items():
        x, y = d.xipos[body][:2]
        if abs(x - centre[0]) > half[0] or abs(y - centre[1]) > half[1]:
            raise InitialStateError(
                f"is off the table: its centre of mass ({x:.3f}, {y:.3f}) m lies outside the table top "
                f"(x {centre[0] - half[0]:.2f}..{centre[0] + half[0]:.2f}, "
                f"y {centre[1] - half[1]:.2f}..{centre[1] + half[1]:.2f} m)", obj=obj, check="off_table")


def deepest_contacts(env, parties: _Parties) -> dict[int, tuple[float, int | str | None]]:
    """Per object: the depth (m, >= 0) of its deepest contact in the current state and what it touches there."""
    d = env.data
    deepest: dict[int, tuple[float, int | str | None]] = {i: (0.0, None) for i in env.grasp.body_of}
    for k in range(d.ncon):
        contact = d.contact[k]
        depth = -float(contact.dist)
        g1, g2 = int(contact.geom[0]), int(contact.geom[1])
        for a, b in ((g1, g2), (g2, g1)):
            obj = int(parties.geom_object[a])
            if obj >= 0 and depth > deepest[obj][0]:
                deepest[obj] = (depth, parties.name(b))
    return deepest


def check_penetration(env, parties: _Parties, when: str) -> dict[int, float]:
    """Raise ``InitialStateError`` if an object is deeper than ``MAX_PENETRATION`` in anything; returns the depths."""
    deepest = deepest_contacts(env, parties)
    for obj, (depth, other) in sorted(deepest.items()):
        if depth > MAX_PENETRATION:
            where = "inside the table" if other == "table" else f"inside {_describe(other)}"
            raise InitialStateError(
                f"is {where} {when}: they interpenetrate by {depth * 1000:.1f} mm (more than "
                f"{MAX_PENETRATION * 1000:.0f} mm); move it apart in the scene", obj=obj, check="penetration",
                other=other)
    return {obj: depth for obj, (depth, _) in deepest.items()}


def support_gap(env, parties: _Parties, obj: int, distmax: float,
                objects: bool = True) -> tuple[float, int | str | None]:
    """The smallest distance (m, up to ``distmax``) from the object's collision geoms to the table (and, with
    ``objects``, to any other object), and which of them is that close."""
    candidates = [parties.table]
    if objects:
        candidates += [g for i, geoms in parties.collision.items() if i != obj for g in geoms]
    # The table's plane-like box is always checked: its bounding sphere says nothing.
    best, which = _closest(env, parties.collision[obj], candidates, distmax, unbounded=parties.table)
    return best, None if which is None else parties.name(which)


def _closest(env, geoms, others, distmax: float, unbounded: int = -1) -> tuple[float, int | None]:
    """The smallest distance (m, up to ``distmax``) from any of ``geoms`` to any of ``others``, and which of
    ``others`` is that close (``None``: none within ``distmax``). Bounding spheres skip pairs that are far apart,
    except with the geom ``unbounded``."""
    m, d = env.model, env.data
    best, which = distmax, None
    if not len(geoms) or not len(others):
        return best, which
    # The pairs whose spheres are apart by more than ``distmax`` (which ``best`` never exceeds) are skipped below
    # whatever is found first: left out at once, all together, with a margin for the sums' rounding.
    mine, theirs = np.asarray(geoms, dtype=int), np.asarray(others, dtype=int)
    apart = ((d.geom_xpos[mine][:, None, :] - d.geom_xpos[theirs][None, :, :]) ** 2).sum(axis=2)
    reach = m.geom_rbound[mine][:, None] + m.geom_rbound[theirs][None, :] + distmax
    kept = (apart <= reach * reach * (1.0 + 1e-9) + 1e-12) | (theirs == unbounded)[None, :]
    for g1, row in zip(geoms, kept):
        for g2 in (others[k] for k in np.flatnonzero(row)):
            reach = m.geom_rbound[g1] + m.geom_rbound[g2] + best
            if g2 != unbounded and np.sum((d.geom_xpos[g1] - d.geom_xpos[g2]) ** 2) > reach * reach:
                continue
            dist = mujoco.mj_geomDistance(m, d, int(g1), int(g2), best, None)
            if dist < best:
                best, which = dist, int(g2)
    return best, which


def robot_clearance(env, clearance: float) -> dict[int, float]:
    """Objects nearer than ``clearance`` (m) to the robot's collision geoms in the current state: id -> distance
    (negative: interpenetrating). An episode starts with the arm at rest; an object there (under a hand that rests
    low over the table, as on the original stage) is in the first move's way before the agent has done anything."""
    parties = _Parties(env)
    m = env.model
    robot = [g for g in np.flatnonzero(parties.robot) if m.geom_contype[g] or m.geom_conaffinity[g]]
    distances = {obj: _closest(env, geoms, robot, clearance)[0] for obj, geoms in parties.collision.items()}
    return {obj: float(dist) for obj, dist in distances.items() if dist < clearance}


def check_supported(env, parties: _Parties) -> None:
    """Raise ``InitialStateError`` for an object with no support (table or object) within ``SUPPORT_GAP``."""
    for obj in sorted(env.grasp.body_of):
        gap, _ = support_gap(env, parties, obj, SUPPORT_GAP)
        if gap < SUPPORT_GAP:
            continue
        table, near = support_gap(env, parties, obj, FLOATING_SEARCH, objects=False)
        height = (f"{table * 1000:.0f} mm above the table" if near is not None
                  else f"more than {FLOATING_SEARCH * 1000:.0f} mm from the table")
        raise InitialStateError(f"is floating: it is {height} and no object supports it within "
                                f"{SUPPORT_GAP * 1000:.0f} mm; put it on its support in the scene",
                                obj=obj, check="floating", other="table")


def _resting_on(env, parties: _Parties, obj: int) -> int | str | None:
    """The table or object this object touches now (contacts within ``SUPPORT_GAP``), or None."""
    d = env.data
    touching = None
    for k in range(d.ncon):
        contact = d.contact[k]
        if contact.dist > SUPPORT_GAP:
            continue
        g1, g2 = int(contact.geom[0]), int(contact.geom[1])
        for a, b in ((g1, g2), (g2, g1)):
            if int(parties.geom_object[a]) == obj and parties.is_support(b, obj):
                if b == parties.table:
                    return "table"
                touching = parties.name(b)
    return touching


def settle(env, duration: float = SETTLE_TIME) -> None:
    """Run ``duration`` s of physics with the arm holding its rest pose and the gripper open."""
    env.servos.command(env.data, env.names.init_qpos)
    env.open_gripper()
    env.advance(duration)


def settle_and_check(env, settle_time: float = SETTLE_TIME) -> InitialStateReport:
    """Check the environment's current state, settle it in place for ``settle_time`` s and check it again.

    Raises ``InitialStateError`` (naming the object and the failed check) if the scene does not start at rest.
    """
    m, d = env.model, env.data
    parties = _Parties(env)
    mujoco.mj_forward(m, d)
    check_masses(env)
    check_over_table(env)
    check_penetration(env, parties, "at the start")
    check_supported(env, parties)

    ids = sorted(env.grasp.body_of)
    bodies = np.array([env.grasp.body_of[i] for i in ids], dtype=int)
    origin0, com0, quat0 = d.xpos[bodies].copy(), d.xipos[bodies].copy(), d.xquat[bodies].copy()
    before = env.snapshot()
    try:
        settle(env, settle_time)
    except PhysicsError as e:
        below = [i for i, b in zip(ids, bodies) if not np.all(np.isfinite(d.xpos[b])) or d.xpos[b][2] < -BELOW_TABLE]
        env.restore(before)
        raise InitialStateError(f"did not settle: {e}", obj=below[0] if below else None, check="unstable") from e
    env.steps = before.steps  # settling is not part of the episode

    report = InitialStateReport(settle_time)
    moved = np.maximum(np.linalg.norm(d.xpos[bodies] - origin0, axis=1), np.linalg.norm(d.xipos[bodies] - com0, axis=1))
    for k, obj in enumerate(ids):
        turned = turn_deg(quat0[k], d.xquat[bodies[k]])
        if not settled(moved[k], turned):
            drop = origin0[k][2] - d.xpos[bodies[k]][2]
            raise InitialStateError(
                f"does not rest: in {settle_time:g} s of settling it moved {moved[k] * 1000:.1f} mm (dropped "
                f"{drop * 1000:.1f} mm) and turned {turned:.1f} degrees (at most {SETTLED_DISPLACEMENT * 1000:.0f} mm "
                f"and {SETTLED_TURN:g} degrees); place it stably in the scene", obj=obj, check="moved")
        report.objects[obj] = ObjectRest(obj, float(moved[k]), turned, 0.0, None)
    depths = check_penetration(env, parties, f"after {settle_time:g} s of settling")
    for obj in ids:
        support = _resting_on(env, parties, obj)
        if support is None:
            raise InitialStateError(f"touches neither the table nor another object after {settle_time:g} s of "
                                    "settling", obj=obj, check="unsupported")
        report.objects[obj].penetration = depths[obj]
        report.objects[obj].support = support
    return report
