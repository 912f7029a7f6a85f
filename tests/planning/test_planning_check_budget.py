"""OMPL's planning budget is work (collision checks), not seconds: the same query ends the same way on an idle and
on a slow, loaded machine."""
from __future__ import annotations

import time

import numpy as np
import pytest

from muble import JointGoal, PlanningError, Pose, PoseGoal
from muble_plugins.planners.ompl_planner import OmplPlanner
from tests.support.tabletop import build_tabletop

WALL = ((0.0, 0.0, 0.95), (0.04, 0.15, 0.15))


class SlowWorld:
    """The same collision world, every check slowed down as on a saturated machine."""

    def __init__(self, world, delay: float):
        self._world, self._delay = world, delay

    def is_valid(self, q):
        time.sleep(self._delay)
        return self._world.is_valid(q)

    def __getattr__(self, name):
        return getattr(self._world, name)


@pytest.fixture(scope="module")
def query():
    scene = build_tabletop("Panda", boxes=[WALL])
    world = scene.collision_world()
    down = world.ee_pose(scene.home_q).quat
    goal_q = world.inverse_kinematics(PoseGoal(Pose(np.array([0.1, -0.3, 0.92]), down)))
    return scene, world, goal_q


def test_a_slow_machine_finds_the_same_path(query):
    scene, world, goal_q = query
    planner = OmplPlanner(try_direct=False, time_limit=60.0)
    fast = planner.plan(scene.home_q, JointGoal(goal_q), world)
    slow = planner.plan(scene.home_q, JointGoal(goal_q), SlowWorld(world, 0.002))
    np.testing.assert_array_equal(fast.q, slow.q)


def test_an_exhausted_budget_fails_the_same_way_however_slow(query):
    scene, world, goal_q = query
    planner = OmplPlanner(try_direct=False, check_budget=20)
    messages = []
    for w in (world, SlowWorld(world, 0.002)):
        with pytest.raises(PlanningError, match="20 collision checks") as info:
            planner.plan(scene.home_q, JointGoal(goal_q), w)
        messages.append(str(info.value))
    assert messages[0] == messages[1]
