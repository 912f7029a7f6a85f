"""A ``CollisionWorld`` over a MuJoCo model: the arm, its gripper and a held object against everything else.

Checks run on a private copy of the model and a private ``MjData`` so the live simulation is never touched.
In the copy, the robot's geoms and the rest of the world sit in different collision classes so that contacts
between resting objects (which are not the planner's business) are never even generated, and the robot's
geoms get a margin so that a configuration closer than ``clearance`` to an obstacle already counts as a hit.
"""
from __future__ import annotations

import contextlib
import copy
import logging
import threading
from collections.abc import Iterable, Iterator

import mujoco
import numpy as np

from muble.core import streams
from muble.core.errors import PlanningError
from muble.core.interfaces import CollisionWorld
from muble.core.object_physics import CONTENTS_COLLISION_CLASS
from muble.core.types import Pose, PoseGoal
from muble.sim.ik import ArmKinematics

logger = logging.getLogger(__name__)

_ROBOT_CLASS = 1  # contype bit of robot (and held object) geoms; conaffinity of everything is 1
_WORLD_CLASS = 2  # contype bit of world geoms: world & world never collide in the check model
# Bits 2-30 of contype/conaffinity: one per robot collision geom, for the robot-robot pairs that count
# (``_detect_counted_self_pairs_only``).
_FIRST_SELF_BIT, _SELF_BITS = 2, 29
LIMIT_TOLERANCE = 0.003  # rad past a joint limit still accepted as valid
RESTING_SLACK = 0.001  # m a contact tolerated by ``resting_at`` may deepen (contact distances vary that much)
_NO_HITS = (np.zeros((0, 2), dtype=int), np.zeros(0))  # the hit geom pairs and distances of a valid check
for _a in _NO_HITS:
    _a.flags.writeable = False


def _subtree_bodies(model: mujoco.MjModel, root: int) -> set[int]:
    bodies = {root}
    for b in range(root + 1, model.nbody):
        if model.body_parentid[b] in bodies:
            bodies.add(b)
    return bodies


# ``solve_on_arm_alone``'s kinematics, per thread (its MjData is scratch), by (id of the model, arm joints, site),
# each with its model (kept, so that its id stays its own).
_arm_alone_cache = threading.local()


def _same_robot(full: mujoco.MjModel, alone: mujoco.MjModel, root: int, site: int, joints) -> bool:
    """Whether ``alone`` holds the robot of ``full`` whose tree starts at body ``root``, every number the
    kinematics read the same (``MujocoCollisionWorld.solve_on_arm_alone``)."""
    try:
        alone_site = alone.site(full.site(site).name).id
        if any(alone.joint(j).id != full.joint(j).id for j in joints):
            return False
    except KeyError:
        return False
    if root >= alone.nbody:
        return False
    bodies = np.flatnonzero(full.body_rootid == root)
    if not np.array_equal(np.flatnonzero(alone.body_rootid == root), bodies) or full.body_rootid[root] != root:
        return False
    body_joints = np.flatnonzero(np.isin(full.jnt_bodyid, bodies))
    dofs = np.flatnonzero(np.isin(full.dof_bodyid, bodies))
    # The robot's joints and degrees of freedom are all of ``alone``'s, first in both.
    if (not np.array_equal(body_joints, np.arange(alone.njnt)) or not np.array_equal(dofs, np.arange(alone.nv))
            or alone.nq != (full.jnt_qposadr[alone.njnt] if alone.njnt < full.njnt else full.nq)):
        return False
    for prefix, rows, alone_rows in (("body_", bodies, bodies), ("jnt_", body_joints, body_joints),
                                     ("dof_", dofs, dofs), ("site_", [site], [alone_site])):
        count = {"body_": full.nbody, "jnt_": full.njnt, "dof_": full.nv, "site_": full.nsite}[prefix]
        for name in dir(full):
            if not name.startswith(prefix) or name.endswith("invweight0"):
                continue
            a = getattr(full, name)
            if not isinstance(a, np.ndarray) or a.shape[:1] != (count,):
                continue
            b = getattr(alone, name)
            if a[rows].tobytes() != b[alone_rows].tobytes():
                return False
    return True


def _steps_up(model: mujoco.MjModel, body: int) -> dict[int, int]:
    """Each body on ``body``'s chain to the world (itself included), with its number of steps up from it."""
    steps, k = {body: 0}, 0
    while body != 0:
        body, k = int(model.body_parentid[body]), k + 1
        steps[body] = k
    return steps


def _chain_distance(a: dict[int, int], b: dict[int, int]) -> int:
    """The tree distance of two bodies from their ``_steps_up``: the fewest steps through a common ancestor."""
    return min(k + b[c] for c, k in a.items() if c in b)


class MujocoCollisionWorld(CollisionWorld):
    """Collision checking and IK for one arm of a MuJoCo model.

    ``robot_root`` is the body whose subtree is the robot (arm links and gripper); ``gripper_root`` the body
    whose subtree is the gripper. ``data`` is the live state: object poses and finger positions are copied from
    it now and on every ``sync``; it is never written.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        arm_joints: list[str],
        ee_site: str,
        robot_root: str,
        gripper_root: str,
        *,
        clearance: float = 0.005,
        ik_restarts: int = 40,
        seed: int = 0,
    ):
        self.model = copy.deepcopy(model)
        self.data = mujoco.MjData(self.model)
        self.kinematics = ArmKinematics(self.model, self.data, arm_joints, ee_site)
        self.clearance = clearance
        self.ik_restarts = ik_restarts
        self.seed = seed
        m = self.model
        self.robot_bodies = _subtree_bodies(m, m.body(robot_root).id)
        self.gripper_bodies = _subtree_bodies(m, m.body(gripper_root).id)
        self._geom_body = m.geom_bodyid.copy()
        # A closed container's inner walls and loose contents lie inside its solid parts: nothing reaches them.
        inside = (m.geom_contype == CONTENTS_COLLISION_CLASS) & (m.geom_conaffinity == CONTENTS_COLLISION_CLASS)
        m.geom_contype[inside] = 0
        m.geom_conaffinity[inside] = 0
        collidable = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
        self._robot_geoms = np.array([collidable[g] and m.geom_bodyid[g] in self.robot_bodies for g in range(m.ngeom)])
        self._gripper_geoms = np.array([m.geom_bodyid[g] in self.gripper_bodies for g in range(m.ngeom)])
        self._world_geoms = collidable & ~self._robot_geoms
        # Robot parts the arm joints do not move (mount, base): objects may rest against them; that is no hit.
        first_link = m.jnt_bodyid[m.joint(arm_joints[0]).id]
        moving = _subtree_bodies(m, first_link)
        self._static_geoms = self._robot_geoms & ~np.isin(m.geom_bodyid, list(moving))
        m.geom_contype[self._robot_geoms] = _ROBOT_CLASS
        m.geom_conaffinity[self._robot_geoms] = 1
        m.geom_contype[self._world_geoms] = _WORLD_CLASS
        m.geom_conaffinity[self._world_geoms] = 1
        m.geom_margin[self._robot_geoms] = clearance
        m.geom_gap[:] = 0.0
        self._held_body: int | None = None
        self._held_geoms = np.zeros(m.ngeom, dtype=bool)
        self._held_qpos_adr: int | None = None
        self._held_offset: tuple[np.ndarray, np.ndarray] | None = None
        self._allowed_bodies: set[int] = set()
        self._allowed_held_only = False
        # Per geom pair, the least distance a contact may have (inf: none tolerated); see ``resting_at``.
        self._tolerated = np.full((m.ngeom, m.ngeom), np.inf)
        self._tolerating = False
        self._ignore_tables: dict[tuple, np.ndarray] = {}  # ``_update_ignore``'s tables by held body and allowances
        self.sync(data)
        self._self_ignore = self._self_collision_filter()
        self._detect_counted_self_pairs_only()
        self._update_ignore()
        self.last_contacts: list[tuple[str, str]] = []
        self._limits: np.ndarray | None = None  # the joint limits ``is_valid`` last worked its accepted range out of
        self._robot_root = m.body(robot_root).id
        self._arm_alone: ArmKinematics | None = None  # ``solve_on_arm_alone``'s kinematics, if any
        self._arm_alone_model: mujoco.MjModel | None = None  # the model last offered to it
        self._scratch: mujoco.MjData | None = None  # ``scratch_data``'s
        self._scratch_user: object = None

    def scratch_data(self, user: object) -> tuple[mujoco.MjData, bool]:
        """(a second ``MjData`` of this world's model for a caller's own computations, made once: making one
        costs milliseconds; whether ``user`` was the last to ask for it, so that it still holds what that user
        left in it). A user that finds it taken sets again every field it reads."""
        if self._scratch is None:
            self._scratch = mujoco.MjData(self.model)
        kept = self._scratch_user is user
        self._scratch_user = user
        return self._scratch, kept

    # ----------------------------------------------------------------- inverse kinematics on the robot alone
    def solve_on_arm_alone(self, model: mujoco.MjModel) -> bool:
        """From now on, solve inverse kinematics on ``model``, a model of this robot without the objects (the
        same world built with no objects on the table), when the robot in it is this world's bit for bit: the same
        iterates, bit for bit, in less time, since MuJoCo's kinematics then skip every object's geoms and sites.
        Whether it is used (``False``: this world's own model; the robot differs in some number).

        Every step of the solver reads only the robot's own tree: ``mj_kinematics`` places each body from its
        parent's frame, ``mj_comPos`` builds the com-based frames of a body from its own tree (summed over that
        tree's bodies in the same order) and ``mj_jacSite`` reads those. So the robot's bodies, joints, degrees of
        freedom and end-effector site must carry the same numbers (all of them but ``*_invweight0``, which the
        compiler works out for the constraint solver from the whole model), with the same ids, its tree holding
        no other body, and its joints first in ``qpos`` in both: then every step computes the same numbers."""
        if model is self._arm_alone_model:
            return self._arm_alone is not None
        self._arm_alone_model, self._arm_alone = model, None
        if _same_robot(self.model, model, self._robot_root, self.kinematics.site_id, self.kinematics.joint_names):
            key = (id(model), self.kinematics.joint_names, self.model.site(self.kinematics.site_id).name)
            cache = _arm_alone_cache.__dict__.setdefault("kinematics", {})
            kept = cache.get(key)
            if kept is None:  # one per model (making its MjData costs a millisecond): ``_solve`` sets all it reads
                kept = cache[key] = (model, ArmKinematics(model, mujoco.MjData(model), list(key[1]), key[2]))
            kinematics = kept[1]
            if (np.array_equal(kinematics.qpos_adr, self.kinematics.qpos_adr)
                    and np.array_equal(kinematics.dof_adr, self.kinematics.dof_adr)):
                self._arm_alone = kinematics
        return self._arm_alone is not None

    def _solve(self, target_pos: np.ndarray, target_quat: np.ndarray | None, seed: np.ndarray, **options):
        """``self.kinematics.solve``, on the robot alone where ``solve_on_arm_alone`` set that up. This world's
        state is then left as solving here leaves it: the arm at the last configuration tried (``arm_q``, the
        default seed of the next solve, reads it) and the kinematics at it."""
        alone = self._arm_alone
        if alone is None:
            return self.kinematics.solve(target_pos, target_quat, seed, **options)
        n = alone.model.nq  # the robot's joints, first in both (``_same_robot``)
        alone.data.qpos[:] = self.data.qpos[:n]  # the fingers as synced: the robot's centre of mass
        alone.limits = self.kinematics.limits
        result = alone.solve(target_pos, target_quat, seed, **options)
        self.data.qpos[:n] = alone.data.qpos
        mujoco.mj_kinematics(self.model, self.data)
        return result

    # ----------------------------------------------------------------- state
    def sync(self, data: mujoco.MjData) -> None:
        """Copy the live state (objects, fingers, arm) into the checking data."""
        self.data.qpos[:] = data.qpos
        mujoco.mj_kinematics(self.model, self.data)
        if self._held_body is not None:
            self._capture_held_offset()

    @property
    def arm_q(self) -> np.ndarray:
        """The arm configuration of the last synced state."""
        return self.data.qpos[self.kinematics.qpos_adr].copy()

    def _self_collision_filter(self) -> np.ndarray:
        """Robot-robot geom pairs never counted: neighbours in the kinematic tree and pairs touching at rest."""
        m = self.model
        robot = np.flatnonzero(self._robot_geoms)
        ignore = np.zeros((m.ngeom, m.ngeom), dtype=bool)
        # Links two joints apart can touch at their shells without real interference; fingers too. The tree
        # distances of the robot geoms' bodies, each body's chain to the world walked once.
        bodies = [int(b) for b in m.geom_bodyid[robot]]
        steps = {b: _steps_up(m, b) for b in set(bodies)}
        near = np.array([[_chain_distance(steps[bi], steps[bj]) <= 2 for bj in bodies] for bi in bodies],
                        dtype=bool).reshape(len(robot), len(robot))
        gripper = self._gripper_geoms[robot]
        ignore[np.ix_(robot, robot)] = near | np.outer(gripper, gripper)
        mujoco.mj_collision(m, self.data)
        for c in self.data.contact[: self.data.ncon]:
            g1, g2 = c.geom
            if self._robot_geoms[g1] and self._robot_geoms[g2]:
                ignore[g1, g2] = ignore[g2, g1] = True
        return ignore

    def _detect_counted_self_pairs_only(self) -> None:
        """Keep MuJoCo from even detecting the robot-robot contacts that never count (``_self_ignore``: the
        fingers against each other, neighbouring links): two thirds of a check's collision detection, spent on
        contacts thrown away. Each robot geom gets a bit of its own in its ``contype`` and its counted partners'
        bits in its ``conaffinity``; the world and held-object classes keep theirs, so every other pair is
        detected as without the bits, in the same order, with the same distances. Left as it is for a robot with more
        collision geoms than bits."""
        m = self.model
        robot = np.flatnonzero(self._robot_geoms)
        if len(robot) > _SELF_BITS:
            return
        bits = {int(g): 1 << (_FIRST_SELF_BIT + k) for k, g in enumerate(robot)}
        for i in robot:
            partners = 0
            for j in robot:
                if i != j and not self._self_ignore[i, j]:
                    partners |= bits[int(j)]
            # World geoms (contype _WORLD_CLASS, conaffinity 1) and a held object (contype _ROBOT_CLASS,
            # conaffinity 1) meet the robot's _ROBOT_CLASS bit; robot geoms meet only through the bits.
            m.geom_contype[i] = _ROBOT_CLASS | bits[int(i)]
            m.geom_conaffinity[i] = _WORLD_CLASS | partners

    # ----------------------------------------------------------------- grasp handling
    def allow_contact(self, bodies: Iterable[str | int], held_only: bool = False) -> None:
        """Contacts of the gripper and the held object with these bodies are allowed (grasp target, support); with
        ``held_only`` those of the held object alone."""
        self._allowed_bodies = {self.model.body(b).id if isinstance(b, str) else int(b) for b in bodies}
        self._allowed_held_only = bool(held_only)
        self._update_ignore()

    def hold(self, body: str | int | None) -> None:
        """The object ``body`` moves rigidly with the hand from now on (``None`` releases it).

        Its pose relative to the end-effector is taken from the last synced state.
        """
        m = self.model
        if self._held_body is not None:
            m.geom_contype[self._held_geoms] = _WORLD_CLASS
            m.geom_margin[self._held_geoms] = 0.0
        if body is None:
            self._held_body, self._held_qpos_adr, self._held_offset = None, None, None
            self._held_geoms[:] = False
            self._update_ignore()
            return
        bid = m.body(body).id if isinstance(body, str) else int(body)
        jnt = m.body_jntadr[bid]
        if jnt < 0 or int(m.jnt_type[jnt]) != int(mujoco.mjtJoint.mjJNT_FREE):
            raise PlanningError(f"body '{m.body(bid).name}' has no free joint; only free objects can be held")
        self._held_body = bid
        self._held_qpos_adr = int(m.jnt_qposadr[jnt])
        self._held_geoms = (m.geom_bodyid == bid) & self._world_geoms
        m.geom_contype[self._held_geoms] = _ROBOT_CLASS
        m.geom_margin[self._held_geoms] = self.clearance
        self._capture_held_offset()
        self._update_ignore()

    def _capture_held_offset(self) -> None:
        d, site = self.data, self.kinematics.site_id
        ee_pos, ee_mat = d.site_xpos[site], d.site_xmat[site].reshape(3, 3)
        obj_pos, obj_mat = d.xpos[self._held_body], d.xmat[self._held_body].reshape(3, 3)
        self._held_offset = (ee_mat.T @ (obj_pos - ee_pos), ee_mat.T @ obj_mat)

    def _place_held(self) -> None:
        d, site = self.data, self.kinematics.site_id
        ee_pos, ee_mat = d.site_xpos[site], d.site_xmat[site].reshape(3, 3)
        rel_pos, rel_mat = self._held_offset
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, (ee_mat @ rel_mat).ravel())
        a = self._held_qpos_adr
        d.qpos[a : a + 3] = ee_pos + ee_mat @ rel_pos
        d.qpos[a + 3 : a + 7] = quat
        mujoco.mj_kinematics(self.model, d)

    # ----------------------------------------------------------------- CollisionWorld
    @property
    def joint_limits(self) -> np.ndarray:
        return self.kinematics.limits.copy()

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.kinematics.joint_names

    def contacts(self, q: np.ndarray) -> list[tuple[str, str]]:
        """Names of the body pairs in collision at ``q`` (empty when valid)."""
        self._collide(q)
        return list(self.last_contacts)

    def _collide(self, q: np.ndarray) -> bool:
        self.kinematics.set_q(q)
        if self._held_body is not None:
            self._place_held()
        m, d = self.model, self.data
        mujoco.mj_collision(m, d)
        self.last_contacts = []
        n = d.ncon
        if n == 0:
            self._hit_geoms, self._hit_dist = _NO_HITS
            return True
        # Python over the few contacts found: numpy's per-call cost is most of a check's time on arrays this small.
        contact = d.contact
        pairs, dists = contact.geom[:n].tolist(), contact.dist[:n].tolist()
        ignore, clearance = self._ignore, self.clearance
        tolerated = self._tolerated if self._tolerating else None
        hits = [k for k in range(n) if dists[k] <= clearance and not ignore[pairs[k][0], pairs[k][1]]
                and (tolerated is None or dists[k] < tolerated[pairs[k][0], pairs[k][1]] - RESTING_SLACK)]
        if not hits:
            self._hit_geoms, self._hit_dist = _NO_HITS
            return True
        self._hit_geoms = np.array([pairs[k] for k in hits], dtype=int)
        self._hit_dist = np.array([dists[k] for k in hits])
        names = m.geom_bodyid
        self.last_contacts = [(m.body(names[pairs[k][0]]).name, m.body(names[pairs[k][1]]).name) for k in hits]
        return False

    def _update_ignore(self) -> None:
        """The geom-pair table of contacts that never count, rebuilt when the held object or allowances change
        (each table kept: a planning query returns to the same few, and the table is never written)."""
        key = (self._held_body, frozenset(self._allowed_bodies), self._allowed_held_only)
        ignore = self._ignore_tables.get(key)
        if ignore is None:
            ignore = self._ignore_tables[key] = self._ignore_table()
        self._ignore = ignore

    def _ignore_table(self) -> np.ndarray:
        m = self.model
        robot = self._robot_geoms | self._held_geoms
        ignore = self._self_ignore.copy()
        static_world = np.outer(self._static_geoms, self._world_geoms & ~self._held_geoms)
        ignore |= static_world | static_world.T
        held_gripper = np.outer(self._held_geoms, self._gripper_geoms)
        ignore |= held_gripper | held_gripper.T
        allowed = np.isin(m.geom_bodyid, list(self._allowed_bodies)) & ~robot
        own = self._held_geoms if self._allowed_held_only else self._gripper_geoms | self._held_geoms
        allowed_pairs = np.outer(own, allowed)
        ignore |= allowed_pairs | allowed_pairs.T
        ignore.flags.writeable = False
        return ignore

    @contextlib.contextmanager
    def resting_at(self, q: np.ndarray) -> Iterator[bool]:
        """Within the block, contacts present at ``q`` count only where they come closer than at ``q`` (by more
        than ``RESTING_SLACK``), so a path may leave them, not push into them. Two kinds are tolerated so:

        - the held object against the other objects or the table (an object taken while it still leans on a
          neighbour, or lifted beside one);
        - the arm's own links inside the planning clearance of each other without touching (distance > 0): a
          tracked move ends within its tracking error of the planned configuration, which may put two links a
          hair inside the clearance the plan kept.

        The arm touching itself, and the arm's or gripper's contacts with anything else, are never tolerated.
        Yields whether ``q`` is valid so."""
        q = np.asarray(q, dtype=float)
        valid = self.is_valid(q)
        if valid:
            yield valid
            return
        self._collide(q)  # the contacts at q (is_valid may have stopped at a joint limit)
        held, robot = self._held_geoms, self._robot_geoms & ~self._held_geoms
        pairs = []
        for (a, b), dist in zip(self._hit_geoms, self._hit_dist):
            a, b, dist = int(a), int(b), float(dist)
            leaning = self._held_body is not None and held[a] != held[b] and not (robot[a] or robot[b])
            own_clearance = robot[a] and robot[b] and dist > 0.0
            if leaning or own_clearance:
                pairs.append((a, b, dist))
        for a, b, dist in pairs:
            self._tolerated[a, b] = self._tolerated[b, a] = min(dist, self._tolerated[a, b])
        self._tolerating = True
        try:
            valid = self.is_valid(q)
            if pairs:
                logger.debug("planning from contacts it may leave %s: %s", sorted(
                    {(self.model.body(self.model.geom_bodyid[a]).name, self.model.body(self.model.geom_bodyid[b]).name)
                     for a, b, _ in pairs}), "valid" if valid else f"still in collision {self.last_contacts[:3]}")
            yield valid
        finally:
            self._tolerating = False
            self._tolerated[:] = np.inf

    def is_valid(self, q: np.ndarray) -> bool:
        lim = self.kinematics.limits
        if lim is not self._limits:  # the limits' accepted range, worked out again only when they are replaced
            self._limits, self._low, self._high = lim, lim[:, 0] - LIMIT_TOLERANCE, lim[:, 1] + LIMIT_TOLERANCE
        # A measured configuration may sit a hair past a limit (servo overshoot): that is no reason to refuse it.
        if (q < self._low).any() or (q > self._high).any():
            return False
        return self._collide(np.asarray(q, dtype=float))

    def forward_kinematics(self, q: np.ndarray) -> np.ndarray:
        return self.kinematics.site_pose(q)[0]

    def ee_pose(self, q: np.ndarray) -> Pose:
        pos, quat = self.kinematics.site_pose(q)
        return Pose(pos, quat)

    def local_inverse_kinematics(self, goal: PoseGoal, seed: np.ndarray) -> np.ndarray:
        """The solution reached from ``seed`` alone (no restarts): continuous motion along a Cartesian path."""
        res = self._solve(goal.pose.pos, goal.pose.quat, seed,
                                    position_tolerance=goal.position_tolerance * 0.5,
                                    orientation_tolerance=goal.orientation_tolerance * 0.5)
        if not res.within(goal.position_tolerance, goal.orientation_tolerance):
            raise PlanningError(f"pose at {np.round(goal.pose.pos, 3).tolist()} not reached from the previous "
                                f"configuration ({res.position_error * 1000:.1f} mm off): joint limit or singularity")
        if not self.is_valid(res.q):
            raise PlanningError(f"pose at {np.round(goal.pose.pos, 3).tolist()} is in collision "
                                f"{self.last_contacts[:3]}")
        return res.q

    def inverse_kinematics(self, goal: PoseGoal, seeds: np.ndarray | None = None) -> np.ndarray:
        """Seeds in order (the synced arm configuration when none), then random restarts within the limits.

        The first solution within tolerance that is also collision-free wins, so a good seed gives the nearby
        solution. Raises ``PlanningError`` saying whether the pose was out of reach or only reached in collision.
        """
        lim = self.kinematics.limits
        ordered = [np.asarray(s, dtype=float) for s in (np.atleast_2d(seeds) if seeds is not None else [self.arm_q])]
        # A fresh generator per call: the same query always gets the same answer, whatever came before. Its older
        # seeding is kept (legacy_stream): the restarts decide the oracle's arm paths in the shipped sequences.
        restarts = streams.legacy_stream(streams.IK_RESTARTS, self.seed).uniform(
            lim[:, 0], lim[:, 1], size=(self.ik_restarts, len(lim)))
        reached_in_collision: list[tuple[str, str]] | None = None
        best_pos_err = np.inf
        for seed in [*ordered, *restarts]:
            res = self._solve(
                goal.pose.pos, goal.pose.quat, seed,
                position_tolerance=goal.position_tolerance * 0.5,
                orientation_tolerance=goal.orientation_tolerance * 0.5,
            )
            best_pos_err = min(best_pos_err, res.position_error)
            if not res.within(goal.position_tolerance, goal.orientation_tolerance):
                continue
            if self.is_valid(res.q):
                return res.q
            reached_in_collision = list(self.last_contacts)
        where = np.round(goal.pose.pos, 3).tolist()
        if reached_in_collision is not None:
            raise PlanningError(
                f"pose at {where} is reachable only in collision ({reached_in_collision[:3]}); "
                "choose a pose with more clearance from other objects"
            )
        raise PlanningError(
            f"pose at {where} is out of reach of the arm (closest IK solution {best_pos_err * 1000:.0f} mm away); "
            "choose a target nearer the robot base or another orientation"
        )
