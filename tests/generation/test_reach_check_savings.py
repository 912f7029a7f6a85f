"""The reach check's savings change no outcome: the collision world detects only the robot-robot contacts that
count, yet reports every check as before; the OMPL planner's ``check`` fails exactly where ``plan`` fails; the
self-collision filter, the IK iterates (on the whole model and on the robot alone), the hand clearance on shared
scratch data and the grasp ranking are those of the code before each saving, bit for bit.
(``test_reach_decisions.py`` holds the check's decisions on 312 recorded layouts.)"""
from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from muble import JointGoal, PlanningError, Pose, PoseGoal, get_registry
from muble.sim.collision_world import MujocoCollisionWorld
from muble.sim.ik import LIMIT_MARGIN, _solve, _solve_errors
from muble_plugins.planners.ompl_planner import OmplPlanner
from tests.support.tabletop import build_tabletop

WALL = ((0.0, 0.0, 0.95), (0.04, 0.15, 0.15))
OBJECT = ((-0.2, 0.15, 0.83), (0.02, 0.02, 0.03))


@pytest.fixture(scope="module")
def scene():
    return build_tabletop("Panda", boxes=[WALL], free_boxes=[OBJECT])


def _every_robot_pair_detected(scene) -> MujocoCollisionWorld:
    """A collision world as it was before: every pair of robot geoms goes through MuJoCo's detection."""
    world = scene.collision_world()
    robot = world._robot_geoms
    world.model.geom_contype[robot] = 1
    world.model.geom_conaffinity[robot] = 1
    return world


def _configurations(scene, world, count: int = 400) -> list[np.ndarray]:
    """Random configurations (many in self-collision) and some near the table, the wall and the object."""
    lim = world.joint_limits
    rng = np.random.default_rng(7)
    qs = list(rng.uniform(lim[:, 0], lim[:, 1], size=(count, len(lim))))
    down = world.ee_pose(scene.home_q).quat
    for target in [(-0.2, 0.15, 0.9), (-0.2, 0.15, 0.86), (-0.05, 0.0, 0.95), (0.1, -0.3, 0.92)]:
        try:
            q = world.inverse_kinematics(PoseGoal(Pose(np.array(target), down)))
        except PlanningError:
            continue
        qs += [scene.home_q + (q - scene.home_q) * f for f in np.linspace(0.2, 1.2, 11)]
    return qs


def test_the_collision_world_reports_every_check_as_when_it_detected_every_robot_pair(scene):
    world, before = scene.collision_world(), _every_robot_pair_detected(scene)
    assert not np.array_equal(world.model.geom_contype, before.model.geom_contype)
    qs = _configurations(scene, world)
    invalid = 0
    for hold in (None, "object"):
        for w in (world, before):
            w.hold(None)
            w.allow_contact([])
            w.sync(scene.data)
            if hold:
                w.hold(scene.object_bodies[0])
        for q in qs:
            valid = world.is_valid(q)
            assert valid == before.is_valid(q)
            assert world.last_contacts == before.last_contacts
            assert world._hit_geoms.tolist() == before._hit_geoms.tolist()
            assert world._hit_dist.tolist() == before._hit_dist.tolist()
            invalid += not valid
    assert invalid > len(qs) // 4  # the comparison saw many collisions


def test_ompl_check_fails_exactly_where_plan_fails(scene):
    world = scene.collision_world()
    down = world.ee_pose(scene.home_q).quat
    behind_the_wall = world.inverse_kinematics(PoseGoal(Pose(np.array([0.1, -0.3, 0.92]), down)))
    planner = OmplPlanner()
    planner.plan(scene.home_q, JointGoal(behind_the_wall), world)
    planner.check(scene.home_q, JointGoal(behind_the_wall), world)
    assert planner.last_used_sampling
    starved = OmplPlanner(check_budget=20, try_direct=False)
    for attempt in (starved.plan, starved.check):
        with pytest.raises(PlanningError, match="no collision-free path"):
            attempt(scene.home_q, JointGoal(behind_the_wall), world)


def _tree_distance(model, a: int, b: int) -> int:
    """Steps between two bodies through their nearest common ancestor, walking both chains for every pair (as the
    collision world did)."""
    def chain(x: int) -> list[int]:
        out = [x]
        while x != 0:
            x = int(model.body_parentid[x])
            out.append(x)
        return out

    ca, cb = chain(a), chain(b)
    return min(ca.index(c) + cb.index(c) for c in set(ca) & set(cb))


def test_the_self_collision_filter_is_the_pairwise_one(scene):
    world = scene.collision_world()
    m = world.model
    robot = np.flatnonzero(world._robot_geoms)
    # The collision classes the filter was first worked out under (before the robot pairs got bits of their own).
    m.geom_contype[robot] = 1
    m.geom_conaffinity[robot] = 1
    expected = np.zeros((m.ngeom, m.ngeom), dtype=bool)
    for i in robot:
        for j in robot:
            near = _tree_distance(m, int(m.geom_bodyid[i]), int(m.geom_bodyid[j])) <= 2
            expected[i, j] = near or (world._gripper_geoms[i] and world._gripper_geoms[j])
    mujoco.mj_collision(m, world.data)
    for c in world.data.contact[: world.data.ncon]:
        g1, g2 = c.geom
        if world._robot_geoms[g1] and world._robot_geoms[g2]:
            expected[g1, g2] = expected[g2, g1] = True
    assert expected.sum() > len(robot)
    assert np.array_equal(world._self_collision_filter(), expected)


def _reference_solve(kin, target_pos, target_quat, seed, position_tolerance=1e-3, orientation_tolerance=1e-2,
                     max_iterations=150, damping=1e-3, max_step=0.2):
    """``ArmKinematics.solve``'s loop as it was before its work arrays were kept between solves and its steps
    written in place (a new array for the damped product, the step's size and every clamped update)."""
    margin = np.minimum(LIMIT_MARGIN, 0.25 * (kin.limits[:, 1] - kin.limits[:, 0]))
    lo, hi = kin.limits[:, 0] + margin, kin.limits[:, 1] - margin
    q = np.clip(np.asarray(seed, dtype=float).copy(), lo, hi)
    rows = 3 if target_quat is None else 6
    err = np.zeros(rows)
    err_w, jac_w = np.empty(rows), np.empty((rows, len(kin.dof_adr)))
    damped = damping * np.eye(rows)
    jacp, jacr = np.zeros((3, kin.model.nv)), np.zeros((3, kin.model.nv))
    quat, conj, diff = np.empty(4), np.empty(4), np.empty(4)
    m, d, site = kin.model, kin.data, kin.site_id
    pos_err = rot_err = np.inf
    it = 0
    with _solve_errors():
        for it in range(1, max_iterations + 1):  # noqa: B007 (returned: the iterations it ran)
            d.qpos[kin.qpos_adr] = q
            mujoco.mj_kinematics(m, d)
            np.subtract(target_pos, d.site_xpos[site], out=err[:3])
            pos_err = math.sqrt(err[:3].dot(err[:3]))
            if target_quat is not None:
                mujoco.mju_mat2Quat(quat, d.site_xmat[site])
                mujoco.mju_negQuat(conj, quat)
                mujoco.mju_mulQuat(diff, target_quat, conj)
                if diff[0] < 0.0:
                    np.negative(diff, out=diff)
                mujoco.mju_quat2Vel(err[3:], diff, 1.0)
                rot_err = math.sqrt(err[3:].dot(err[3:]))
            else:
                rot_err = 0.0
            if pos_err <= position_tolerance and rot_err <= orientation_tolerance:
                break
            mujoco.mj_comPos(m, d)
            mujoco.mj_jacSite(m, d, jacp, jacr, site)
            if rows == 6:
                jac_w[:3] = jacp[:, kin.dof_adr]
                jac_w[3:] = jacr[:, kin.dof_adr]
                jac_w[3:] *= 0.2
                err_w[:] = err
                err_w[3:] *= 0.2
            else:
                jac_w, err_w = jacp[:, kin.dof_adr], err
            jjt = jac_w @ jac_w.T + damped
            dq = jac_w.T @ _solve(jjt, err_w)
            step = np.abs(dq).max()
            if step > max_step:
                dq *= max_step / step
            q = np.minimum(np.maximum(q + dq, lo), hi)
    return q, pos_err, rot_err, it


def test_inverse_kinematics_gives_the_reference_iterates_bit_for_bit(scene):
    world = scene.collision_world()
    kin = world.kinematics
    down = world.ee_pose(scene.home_q).quat
    lim = world.joint_limits
    rng = np.random.default_rng(3)
    converged = maxed = 0
    for k in range(60):
        target = np.array([-0.2, 0.0, 0.9]) + rng.uniform(-0.5, 0.5, 3)
        seed = rng.uniform(lim[:, 0], lim[:, 1])
        quat = None if k % 4 == 3 else down
        options = {"position_tolerance": 0.002, "orientation_tolerance": 0.025} if k % 2 else {}
        got = kin.solve(target, quat, seed, **options)
        q, pos_err, rot_err, it = _reference_solve(kin, target, quat, seed, **options)
        assert got.q.tobytes() == q.tobytes()
        assert (got.position_error, got.orientation_error, got.iterations) == (pos_err, rot_err, it)
        converged += it < 150
        maxed += it == 150
    assert converged > 10 and maxed > 5  # both ends of the loop were compared


def test_grasp_candidates_rank_as_when_every_frame_was_swept_and_composed_per_scene():
    from muble_plugins.primitives import grasping

    objects = get_registry().create("object_set", "shopvrb2", {"cache_dir": None})
    rng = np.random.default_rng(5)
    compared = 0
    for category in objects.categories():
        model = objects.build(objects.sample(rng, category=category))
        if not model.grasp_frames:
            continue
        quat = np.array([np.cos(0.3), 0.0, 0.0, np.sin(0.3)])
        pose = Pose(rng.uniform(-0.3, 0.3, 3), quat)

        def clearance(site: Pose) -> float:  # any function of the pose: the ranking's input
            return float(abs(np.sin(40.0 * site.pos[0]) * 0.03 + site.pos[1] * 0.01))

        for free in (None, clearance):
            for limit in (None, 16):
                got = grasping.grasp_candidates(pose, model, -0.05, max_width=0.075, rest_quat=quat,
                                                clearance=free, limit=limit)
                want = _reference_candidates(pose, model, -0.05, 0.075, quat, free, limit)
                assert [(p.pos.tobytes(), p.quat.tobytes()) for p in got] == \
                       [(p.pos.tobytes(), p.quat.tobytes()) for p in want]
                compared += len(got)
    assert compared > 500


def _reference_candidates(object_pose, model, table_top, max_width, rest_quat, clearance, limit):
    """``grasp_candidates`` without a gripper as it was before each object's swept frames were kept: every frame
    swept and composed with the object's pose one by one."""
    from muble.stage.geometry import mujoco_quat_matrix
    from muble_plugins.primitives.grasping import (CLEAR_ENOUGH, CROWDED, TABLE_CLEARANCE, TOUCHING, _axis,
                                                   _compose, _sweeps, _swept, _turned)

    rest_x = mujoco_quat_matrix(rest_quat) @ np.array([1.0, 0.0, 0.0])
    drafts = []
    for index, frame in enumerate(model.grasp_frames):
        if not 0.0 <= frame.width <= max_width:
            continue
        on_axis = float(np.hypot(frame.position[0], frame.position[1])) < 1e-3
        sweeps = [(0.0, 1.0)]
        if clearance is not None:
            sweeps = _sweeps(frame, model.grasp_frames, on_axis, model.grasp_type)
        for sweep, stretch in sweeps:
            position, frame_quat = _swept(frame, sweep, stretch)
            pos, quat = _compose(object_pose.pos, object_pose.quat, position, frame_quat)
            yaws = [0.0, np.pi]
            if model.grasp_type == "box" or (model.grasp_type == "cylinder" and on_axis):
                yaws += [np.pi / 2, -np.pi / 2]
            for yaw in yaws:
                q = _turned(quat, yaw)
                approach, closing = _axis(q, 2), _axis(q, 0)
                p = pos.copy()
                p[2] = max(p[2], table_top + TABLE_CLEARANCE)
                tilt = float(np.arccos(np.clip(-approach[2], -1.0, 1.0)))
                turn = float(np.arccos(min(1.0, abs(float(closing @ rest_x)))))
                score = tilt + 0.3 * turn + 0.002 * index + 0.001 * abs(sweep)
                drafts.append((score, len(drafts), Pose(p, q), frame.width * stretch, sweep))
    if clearance is None:
        drafts.sort(key=lambda item: item[:2])
        return [d[2] for d in drafts[:limit]]
    scored = []
    for score, rank, site, _, sweep in drafts:
        free = clearance(site)
        if sweep != 0.0 and free < TOUCHING:
            continue
        score += CROWDED if free < TOUCHING else max(0.0, CLEAR_ENOUGH - free) / CLEAR_ENOUGH
        scored.append((score, rank, site))
    scored.sort(key=lambda item: item[:2])
    return [pose for *_, pose in scored[:limit]]


def test_inverse_kinematics_on_the_robot_alone_gives_the_same_iterates_and_leaves_the_same_state():
    import copy
    import gzip
    import json
    from pathlib import Path

    from muble.core.scene import SceneGraph
    from muble.io.scene_io import scene_from_dict
    from muble.sim.build import object_models
    from muble.sim.env import TabletopEnv

    with gzip.open(Path(__file__).parent / "data" / "reach_decisions.json.gz", "rt") as f:
        record = json.load(f)["layouts"][0]
    scene = scene_from_dict(record["scene"])
    env = TabletopEnv(scene, object_models(scene, get_registry().create("object_set", "shopvrb2")), None, {},
                      visual=False)
    alone = TabletopEnv(SceneGraph(), {}, {"stage": env.names.stage}, {}, visual=False)
    assert alone.model.nbody < env.model.nbody and alone.model.ngeom < env.model.ngeom

    def world() -> MujocoCollisionWorld:
        return MujocoCollisionWorld(env.model, env.data, env.arm_joint_names, env.ee_site, "robot0_base",
                                    env.names.hand_body, ik_restarts=4)

    own, fast = world(), world()
    assert fast.solve_on_arm_alone(alone.model)
    different = copy.deepcopy(alone.model)
    different.body_mass[different.body("robot0_link3").id] += 1e-9
    assert not world().solve_on_arm_alone(different)

    down = own.ee_pose(own.arm_q).quat
    rng = np.random.default_rng(11)
    outcomes = set()
    for _ in range(24):
        goal = PoseGoal(Pose(np.array([0.45, -0.1, 0.95]) + rng.uniform(-0.35, 0.35, 3), down))
        results = []
        for w in (own, fast):
            try:
                results.append(("q", w.inverse_kinematics(goal).tobytes()))
            except PlanningError as e:
                results.append(("error", str(e)))
            results.append(("state", w.data.qpos.tobytes(), w.data.geom_xpos.tobytes(), w.arm_q.tobytes()))
            try:
                results.append(("local", w.local_inverse_kinematics(goal, w.arm_q).tobytes()))
            except PlanningError as e:
                results.append(("local error", str(e)))
        assert results[:3] == results[3:]
        outcomes.add((results[0][0], results[2][0]))
    assert len(outcomes) > 1  # solved and failed goals were both compared


class _NewDataPerCaller:
    """A collision world whose ``scratch_data`` is a new MjData for every caller, as ``hand_clearance`` made one
    before it shared the world's."""

    def __init__(self, world):
        self.world, self.made = world, {}

    def __getattr__(self, name):
        return getattr(self.world, name)

    def scratch_data(self, user):
        if user not in self.made:
            self.made[user] = mujoco.MjData(self.world.model)
        return self.made[user], True


def test_hand_clearance_measures_the_same_on_the_world_s_shared_scratch_data(scene):
    from muble_plugins.primitives.grasping import hand_clearance

    world = scene.collision_world()
    world.sync(scene.data)
    quat = world.ee_pose(scene.home_q).quat
    wall, target = scene.box_bodies[0], scene.object_bodies[0]
    first, first_ref = hand_clearance(world, wall), hand_clearance(_NewDataPerCaller(world), wall)
    # The object moved: a second measure on the same scratch data, then the first asked again, which must still
    # see the object where it was.
    adr = scene.model.jnt_qposadr[scene.model.body(target).jntadr[0]]
    world.data.qpos[adr:adr + 3] += [0.05, 0.02, 0.0]
    second, second_ref = hand_clearance(world, wall), hand_clearance(_NewDataPerCaller(world), wall)
    rng = np.random.default_rng(2)
    values = []
    for pos in np.array([-0.17, 0.16, 0.86]) + rng.uniform(-0.08, 0.08, size=(40, 3)):
        for f, ref in ((first, first_ref), (second, second_ref), (first, first_ref)):
            got = f(Pose(pos, quat))
            assert got == ref(Pose(pos, quat))
            values.append(got)
    assert min(values) < 0.002 and max(values) == 0.02 and len(set(values)) > 20
    assert any(first(Pose(p, quat)) != second(Pose(p, quat)) for p in np.array([-0.17, 0.16, 0.86])
               + rng.uniform(-0.08, 0.08, size=(40, 3)))  # the two states differ where measured
