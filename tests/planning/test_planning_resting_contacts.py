"""Objects that rest against each other never make an arm configuration invalid; a held object that still rests
against a neighbour may be carried away from it, not into it."""
from __future__ import annotations

import numpy as np
import pytest

from muble import JointGoal, PlanningError, Pose, PoseGoal
from muble_plugins.planners.ompl_planner import OmplPlanner
from tests.support.tabletop import build_tabletop

TOP = 0.8 + 0.025  # table top (table_height + half its thickness)
HALF = (0.02, 0.02, 0.02)
# Two boxes side by side along x, touching face to face, both resting on the table.
TOUCHING = [((0.05, 0.0, TOP + 0.02), HALF), ((0.09, 0.0, TOP + 0.02), HALF)]


@pytest.fixture(scope="module")
def scene():
    return build_tabletop("Panda", free_boxes=TOUCHING)


def _q_with_hand_moved(world, q, delta):
    pose = world.ee_pose(q)
    return world.inverse_kinematics(PoseGoal(Pose(pose.pos + np.asarray(delta), pose.quat), 0.002, 0.02),
                                    seeds=q[None])


def test_objects_touching_at_rest_leave_every_arm_configuration_valid(scene):
    world = scene.collision_world()
    assert world.is_valid(scene.home_q)
    q = _q_with_hand_moved(world, scene.home_q, (0.0, 0.1, -0.05))
    assert world.is_valid(q) and not world.contacts(q)
    OmplPlanner().plan(scene.home_q, JointGoal(q), world)


def test_a_held_object_resting_against_a_neighbour_can_be_carried_away_not_into_it(scene):
    world = scene.collision_world()
    a, b = scene.object_bodies
    world.hold(a)  # held where it stands: against b and on the table, as just after a grasp
    start = scene.home_q
    assert not world.is_valid(start)
    assert {tuple(sorted(p)) for p in world.last_contacts} >= {tuple(sorted((a, b)))}
    up = _q_with_hand_moved(scene.collision_world(), start, (-0.02, 0.0, 0.05))
    # Before resting contacts were tolerated this raised "start configuration is in collision [(a, b)]".
    OmplPlanner().plan(start, JointGoal(up), world)
    with world.resting_at(start) as valid:
        assert valid
        into = _q_with_hand_moved(scene.collision_world(), start, (0.01, 0.0, 0.0))
        assert not world.is_valid(into)  # pushing the held box into its neighbour still counts
    assert not world.is_valid(start)  # the tolerance ends with the plan


def test_the_arm_itself_touching_an_object_is_never_tolerated(scene):
    world = scene.collision_world()
    a, b = scene.object_bodies
    pose = world.ee_pose(scene.home_q)
    # The hand lowered onto the second box while the first is held: the gripper's own contact makes it invalid.
    box = np.array(TOUCHING[1][0])
    q = world.kinematics.solve(np.array([box[0], box[1], box[2] - 0.01]), pose.quat, scene.home_q).q
    assert any(b in pair for pair in world.contacts(q))
    world.hold(a)
    with world.resting_at(q) as valid:
        assert not valid
        assert any(b in pair and any(n.startswith("gripper") for n in pair) for pair in world.last_contacts), \
            world.last_contacts
    with pytest.raises(PlanningError, match="start configuration is in collision"):
        OmplPlanner().plan(q, JointGoal(scene.home_q), world)


# A folded arm hovering over an object close to the base, as a tracked move left it: link 2 and link 5 are 4.9 mm
# apart, a hair inside the planning clearance (5 mm) the planned goal kept. Turning joint 4 (index 3) by 0.05 rad
# opens the fold; the other way the links interpenetrate.
FOLDED = np.array([-2.004, -0.527, 1.69, -2.875, -1.649, 3.699, 2.235])


def test_the_arm_a_hair_inside_its_own_clearance_may_move_away_not_closer():
    scene = build_tabletop("Panda", free_boxes=[])
    world = scene.collision_world()
    assert not world.is_valid(FOLDED)
    assert {tuple(sorted(p)) for p in world.last_contacts} == {("robot0_link2", "robot0_link5")}
    opened, deeper = FOLDED.copy(), FOLDED.copy()
    opened[3] += 0.05
    deeper[3] -= 0.05
    with world.resting_at(FOLDED) as valid:
        assert valid
        assert world.is_valid(opened) and not world.is_valid(deeper)
    assert not world.is_valid(FOLDED)  # the tolerance ends with the block
    # Before the arm's own clearance was tolerated this raised "start configuration is in collision".
    OmplPlanner().plan(FOLDED, JointGoal(scene.home_q), world)
    # Links that touch are never a start to plan from.
    with world.resting_at(deeper) as valid:
        assert not valid
    with pytest.raises(PlanningError, match="start configuration is in collision"):
        OmplPlanner().plan(deeper, JointGoal(scene.home_q), world)
