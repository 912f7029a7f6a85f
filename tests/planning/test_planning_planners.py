"""IK, collision checking and both planners on a real robosuite arm beside a table with obstacle boxes."""
from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from omegaconf import OmegaConf

from muble import ConfigError, JointGoal, PlanningError, Pose, PoseGoal, get_registry
from muble.plugins.registry import validate_params
from muble_plugins.planners.ompl_planner import OmplPlanner
from muble_plugins.planners.straight_line import StraightLinePlanner
from muble_plugins.planners.timing import time_parameterise
from tests.support.tabletop import build_tabletop

WALL = ((0.0, 0.0, 0.95), (0.04, 0.15, 0.15))  # a wall on the table between the hand's home and the far side
PILLAR = ((0.0, 0.25, 0.9), (0.02, 0.02, 0.1))
OBJECT = ((-0.2, 0.15, 0.83), (0.02, 0.02, 0.03))


@pytest.fixture(scope="module")
def scene():
    return build_tabletop("Panda", boxes=[WALL, PILLAR], free_boxes=[OBJECT])


@pytest.fixture()
def world(scene):
    return scene.collision_world()


def _top_down(world, scene):
    return world.ee_pose(scene.home_q).quat


def test_ik_reaches_poses_within_joint_limits(scene, world):
    down = _top_down(world, scene)
    for target in [(-0.15, -0.2, 0.9), (-0.2, 0.15, 1.0), (0.2, -0.25, 0.95)]:
        goal = PoseGoal(Pose(np.array(target), down))
        q = world.inverse_kinematics(goal)
        lim = world.joint_limits
        assert np.all(q >= lim[:, 0]) and np.all(q <= lim[:, 1])
        pose = world.ee_pose(q)
        assert np.linalg.norm(pose.pos - target) <= goal.position_tolerance
        assert abs(np.dot(pose.quat, down)) > np.cos(goal.orientation_tolerance / 2)
        assert world.is_valid(q)


def test_ik_out_of_reach_raises_planning_error(scene, world):
    with pytest.raises(PlanningError, match="out of reach"):
        world.inverse_kinematics(PoseGoal(Pose(np.array([1.5, 0.0, 1.0]), _top_down(world, scene))))


def test_ik_inside_an_obstacle_raises_planning_error(scene, world):
    with pytest.raises(PlanningError, match="only in collision"):
        world.inverse_kinematics(PoseGoal(Pose(np.array(WALL[0]), _top_down(world, scene))))


def test_ompl_goes_around_the_wall(scene, world):
    planner = OmplPlanner()
    goal = PoseGoal(Pose(np.array([0.15, -0.1, 1.0]), _top_down(world, scene)))
    # The direct joint-space segment crosses the wall, so the planner has to sample.
    goal_q = world.inverse_kinematics(PoseGoal(Pose(np.array([0.1, -0.3, 0.92]), _top_down(world, scene))))
    trajectory = planner.plan(scene.home_q, JointGoal(goal_q), world)
    assert planner.last_used_sampling
    np.testing.assert_allclose(trajectory.q[0], scene.home_q)
    np.testing.assert_allclose(trajectory.q[-1], goal_q, atol=1e-9)
    for t in np.linspace(0.0, trajectory.duration, 400):
        assert world.is_valid(trajectory.sample(t)), world.last_contacts
    trajectory = planner.plan(scene.home_q, goal, world)
    assert np.linalg.norm(world.forward_kinematics(trajectory.q[-1]) - goal.pose.pos) <= goal.position_tolerance


def test_ompl_failure_is_planning_error_and_live_state_is_untouched(scene, world):
    before = scene.data.qpos.copy()
    goal_q = world.inverse_kinematics(PoseGoal(Pose(np.array([0.1, -0.3, 0.92]), _top_down(world, scene))))
    with pytest.raises(PlanningError, match="no collision-free path"):
        OmplPlanner(time_limit=1e-4, planner="RRT").plan(scene.home_q, JointGoal(goal_q), world)
    # Tip the shoulder forward until the hand is in the table or the wall: a start that is in collision.
    inside = next(q for q in (scene.home_q + np.eye(len(scene.home_q))[1] * a for a in np.arange(0.1, 1.5, 0.1))
                  if not world.is_valid(q))
    with pytest.raises(PlanningError, match="start configuration is in collision"):
        OmplPlanner().plan(inside, JointGoal(scene.home_q), world)
    np.testing.assert_array_equal(scene.data.qpos, before)


def test_straight_line_keeps_the_hand_on_the_line(scene, world):
    start = world.ee_pose(scene.home_q)
    goal = PoseGoal(Pose(start.pos + np.array([-0.05, -0.05, -0.1]), start.quat))
    trajectory = StraightLinePlanner().plan(scene.home_q, goal, world)
    direction = (goal.pose.pos - start.pos) / np.linalg.norm(goal.pose.pos - start.pos)
    for q in trajectory.q:
        p = world.forward_kinematics(q) - start.pos
        off_line = np.linalg.norm(p - np.dot(p, direction) * direction)
        assert off_line < 0.004
    assert np.linalg.norm(world.forward_kinematics(trajectory.q[-1]) - goal.pose.pos) <= goal.position_tolerance
    speeds = np.abs(np.diff(trajectory.q, axis=0)) / np.diff(trajectory.t)[:, None]
    assert speeds.max() <= 1.0 + 1e-6


def test_straight_line_into_an_obstacle_raises(scene, world):
    q = world.inverse_kinematics(PoseGoal(Pose(np.array([0.0, 0.25, 1.1]), _top_down(world, scene))))
    goal = PoseGoal(Pose(np.array([0.0, 0.25, 0.9]), _top_down(world, scene)))  # down through the pillar
    with pytest.raises(PlanningError, match="straight line"):
        StraightLinePlanner().plan(q, goal, world)


def test_grasp_target_contact_allowed_and_held_object_checked():
    scene = build_tabletop("Panda", boxes=[PILLAR], free_boxes=[OBJECT])
    world = scene.collision_world()
    down = _top_down(world, scene)
    grasp = PoseGoal(Pose(np.array(OBJECT[0]), down))
    with pytest.raises(PlanningError, match="only in collision"):
        world.inverse_kinematics(grasp)  # the closed fingers overlap the object
    world.allow_contact([scene.object_bodies[0]])
    q_grasp = world.inverse_kinematics(grasp)
    world.allow_contact([])
    # Hand just above the pillar: the fingertips clear it, a 6 cm box held between them would not.
    pillar_top = PILLAR[0][2] + PILLAR[1][2]
    above = PoseGoal(Pose(np.array([PILLAR[0][0], PILLAR[0][1], pillar_top + OBJECT[1][2] + 0.002]), down))
    q_above = world.inverse_kinematics(above)
    assert world.is_valid(q_above)
    world.data.qpos[world.kinematics.qpos_adr] = q_grasp  # as if the arm had closed on the object
    mujoco.mj_kinematics(world.model, world.data)
    world.hold(scene.object_bodies[0])
    assert not world.is_valid(q_above)
    assert any("object0_main" in pair and "obstacle0_main" in pair for pair in world.last_contacts)
    # Still resting on the table: that contact counts until the support is allowed (as when lifting off it);
    # the held object against its own fingers never counts.
    assert not world.is_valid(q_grasp)
    assert all(pair == ("object0_main", "table") or pair == ("table", "object0_main") for pair in world.last_contacts)
    world.allow_contact(["table"])
    assert world.is_valid(q_grasp)
    world.allow_contact([])
    world.hold(None)
    assert world.is_valid(q_above)


def test_time_parameterisation_respects_limits():
    path = np.array([[0.0, 0.0], [1.0, -0.5], [1.0, 0.5]])
    trajectory = time_parameterise(path, max_velocity=0.5, max_acceleration=1.0, sample_period=0.01)
    velocity = np.diff(trajectory.q, axis=0) / np.diff(trajectory.t)[:, None]
    assert np.abs(velocity).max() <= 0.5 + 1e-6
    acceleration = np.diff(velocity, axis=0) / np.diff(trajectory.t)[1:, None]
    assert np.abs(acceleration).max() <= 1.0 * 1.6  # finite differences of a trapezoid overshoot a little
    for waypoint in path:
        assert np.min(np.linalg.norm(trajectory.q - waypoint, axis=1)) < 1e-9


@pytest.mark.parametrize("robot", ["Sawyer", "UR5e"])
def test_other_arms_plan_to_a_pose_over_the_table(robot):
    scene = build_tabletop(robot, boxes=[PILLAR])
    world = scene.collision_world()
    down = world.ee_pose(scene.home_q).quat
    goal = PoseGoal(Pose(np.array([0.05, -0.15, 0.95]), down))
    trajectory = OmplPlanner().plan(scene.home_q, goal, world)
    assert np.linalg.norm(world.forward_kinematics(trajectory.q[-1]) - goal.pose.pos) <= goal.position_tolerance
    assert all(world.is_valid(q) for q in trajectory.q)


def test_planners_are_registered_with_checked_options():
    registry = get_registry()
    assert {"ompl", "straight_line"} <= set(registry.names("planner"))
    planner = registry.create("planner", "ompl", {"planner": "RRTstar", "time_limit": 0.5})
    assert planner.config.planner == "RRTstar"
    with pytest.raises(ConfigError, match="RRTConnect"):
        registry.create("planner", "ompl", {"planner": "NoSuchPlanner"})
    with pytest.raises(ConfigError, match="time_limit"):
        registry.create("planner", "ompl", {"time_limt": 1.0})
    conf = Path(__file__).resolve().parents[2] / "muble_conf" / "planner"
    for name in ("ompl", "straight_line"):
        values = OmegaConf.to_container(OmegaConf.load(conf / f"{name}.yaml"))
        assert values.pop("defaults") == [f"{name}_schema", "_self_"]
        record = registry.get("planner", name).record
        registry.create("planner", name, validate_params("planner", record, values))
