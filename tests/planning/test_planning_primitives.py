"""Primitive actions on a real five-object tabletop: pick up, weigh, put down, stack, failures."""
from __future__ import annotations

import numpy as np
import pytest

from muble import ConfigError, PlanningError, get_registry
from muble.core.params import specs
from muble.sim.env import TabletopEnv
from tests.support.scenes import five_object_scene


@pytest.fixture(scope="module")
def env():
    scene, models = five_object_scene()
    environment = TabletopEnv(scene, models)
    yield environment
    environment.close()


def act(env, name, **params):
    return get_registry().create("primitive", name, params).execute(env)


def test_every_primitive_is_registered_with_declared_params():
    registry = get_registry()
    expected = {"move", "approach", "close_gripper", "open_gripper", "lift", "lower", "weigh", "reweigh", "squeeze",
                "push", "balance", "shake", "move_vel"}
    assert expected <= set(registry.names("primitive"))
    declared = specs(registry.get("primitive", "move_vel").record.factory.params)
    assert [(p.name, p.kind, p.required) for p in declared] == [("velocity", "vector", True), ("duration", "number", False)]
    with pytest.raises(ConfigError, match="target"):
        registry.create("primitive", "approach", {"object": 1})


def test_pick_weigh_and_put_down_on_a_table_part(env):
    env.reset()
    truth = env.object_models[1].spec.weight_g
    for name, params in [("approach", {"target": 1}), ("close_gripper", {}), ("lift", {})]:
        result = act(env, name, **params)
        assert result.success, (name, result.failure_reason)
        assert result.info.get("unintended_contacts", []) == []
    assert env.held_object == 1
    assert env.object_pose(1).pos[2] > 0.1
    grams = act(env, "weigh").measurement
    assert abs(grams - truth) / truth < 0.01
    result = act(env, "lower", target="right")
    assert result.success, result.failure_reason
    assert result.info["unintended_contacts"] == []
    pos = env.object_pose(1).pos
    assert pos[1] > env.data.geom_xpos[env.model.geom("table_collision").id][1] + 0.05  # right = +y
    assert abs(pos[2]) < 0.005  # resting on the table top (z = 0)
    others = [env.object_pose(i).pos[:2] for i in range(5) if i != 1]
    assert min(np.linalg.norm(pos[:2] - o) for o in others) > 0.06


def test_stack_one_box_on_another(env):
    env.reset()
    for name, params in [("approach", {"target": 2}), ("close_gripper", {}), ("lift", {}),
                         ("move", {"target": 4})]:
        assert act(env, name, **params).success, name
    result = act(env, "lower", target=4)
    assert result.success, result.failure_reason
    env.hold(0.5)
    top = env.object_pose(2).pos
    base = env.object_pose(4).pos
    assert np.linalg.norm(top[:2] - base[:2]) < 0.02
    assert abs(top[2] - (base[2] + env.object_models[4].extents[2])) < 0.005  # resting on its top face


def test_planning_failures_leave_the_state_unchanged(env):
    env.reset()
    before = env.snapshot().state.copy()
    with pytest.raises(PlanningError, match="valid table part names"):
        act(env, "move", target="ceiling")
    with pytest.raises(PlanningError, match="valid object id names"):
        act(env, "approach", target=42)
    with pytest.raises(PlanningError, match="needs an object in the hand"):
        act(env, "lower", target="left")
    np.testing.assert_array_equal(env.snapshot().state, before)
    assert not act(env, "weigh").success


def test_move_vel_moves_the_hand_at_the_given_velocity(env):
    env.reset()
    moved = np.array(act(env, "move_vel", velocity=[0.0, 0.05, 0.0], duration=1.0).measurement)
    assert abs(moved[1] - 0.05) < 0.01
    assert np.all(np.abs(moved[[0, 2]]) < 0.01)
