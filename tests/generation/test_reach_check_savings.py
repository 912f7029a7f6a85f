"""The reach check's savings change no outcome: the collision world detects only the robot-robot contacts that
count, yet reports every check as before; the OMPL planner's ``check`` fails exactly where ``plan`` fails.
(``test_reach_decisions.py`` holds the check's decisions on 312 recorded layouts.)"""
from __future__ import annotations

import numpy as np
import pytest

from muble import JointGoal, PlanningError, Pose, PoseGoal
from muble.sim.collision_world import MujocoCollisionWorld
from muble.sim.tabletop import build_tabletop
from muble_plugins.planners.ompl_planner import OmplPlanner

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
