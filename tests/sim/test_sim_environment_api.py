"""The environment API plugins rely on (``muble.core.environment.Environment``): the tabletop environment provides
every member of it, its answers match the physics, and the docs' example primitive runs on it. (That no built-in
plugin reaches past it into ``muble.sim`` is a rule of tests/core/test_core_layering.py.)"""
import inspect
from pathlib import Path

import mujoco
import numpy as np
import pytest

import muble
from muble.core.environment import Environment, EnvironmentNames
from muble.sim.env import TabletopEnv
from muble.stage.table import part_box
from tests.sim.conftest import pick

PLUGINS = Path(muble.__file__).resolve().parents[1] / "muble_plugins"


def _members(protocol: type) -> set[str]:
    names = set(getattr(protocol, "__annotations__", {}))
    names |= {n for n, v in vars(protocol).items() if not n.startswith("_") and (callable(v) or isinstance(v, property))}
    return names


def test_sim_tabletop_env_provides_every_member_of_the_environment_api(panda_env):
    env = panda_env
    assert isinstance(env, Environment)
    missing = sorted(n for n in _members(Environment) if not hasattr(env, n))
    assert not missing, f"TabletopEnv lacks {missing} of muble.core.environment.Environment"
    missing = sorted(n for n in _members(EnvironmentNames) if not hasattr(env.names, n))
    assert not missing, f"env.names lacks {missing} of muble.core.environment.EnvironmentNames"
    for name, member in vars(Environment).items():
        if callable(member) and not name.startswith("_"):
            declared = list(inspect.signature(member).parameters)
            actual = list(inspect.signature(getattr(TabletopEnv, name)).parameters)
            assert actual[:len(declared)] == declared, f"{name}: {actual} does not start with {declared}"


def test_sim_environment_geometry_answers_match_the_physics(panda_env, scene_models):
    env = panda_env
    env.reset()
    env.hold(0.3)  # let the objects settle into their resting contacts
    _, models = scene_models
    table = env.table()
    assert table.top_z == pytest.approx(0.0, abs=1e-6)  # the scene frame's table top is z = 0
    assert env.object_ids == sorted(models)
    for obj_id in env.object_ids:
        # standing upright on the table top (z = 0): the highest point is the object's height
        top, height = env.object_top(obj_id), env.object_bbox(obj_id)["z"]
        assert height == pytest.approx(models[obj_id].extents[2], abs=0.002)
        assert top == pytest.approx(height, abs=0.003), f"object {obj_id}: top {top:.4f} m, height {height:.4f} m"
        assert env.touches_support(obj_id), f"object {obj_id} rests on the table"
        assert not env.is_raised(obj_id) and not env.is_lifted(obj_id)
    lo, hi = part_box(env, "left")
    assert (lo < hi).all() and hi[1] <= 0.0  # "left" is -y, seen from the scene camera
    # the top-down grasp frame points the grip site's z axis down, and yaw turns it about the vertical
    for yaw in (0.0, 0.7):
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, env.top_down(yaw))
        assert rot.reshape(3, 3)[:, 2] @ [0.0, 0.0, -1.0] == pytest.approx(1.0, abs=0.02)


def test_sim_environment_lifting_and_weighing_through_the_api(panda_env, scene_models):
    env = panda_env
    env.reset()
    _, models = scene_models
    pick(env, 2, models[2].extents[2])
    assert env.held_object == 2
    assert env.is_raised(2) and env.is_lifted(2) and not env.touches_support(2)
    grams = env.weigh()
    assert grams == pytest.approx(models[2].mass * 1000.0, abs=max(1.0, 0.01 * models[2].mass * 1000.0))
    assert env.measurements[2]["weight"] == grams
    world = env.collision_world()
    assert world is env.collision_world()  # built once, re-synced on every call
    assert world.is_valid(env.arm_q())


def test_sim_the_docs_primitive_that_plans_its_own_motion_runs(panda_env):
    """docs/plugins.md's ``Hover`` example, taken from the page as written, plans and moves the real arm."""
    text = (PLUGINS.parent / "docs" / "plugins.md").read_text()
    code = text.split("A primitive that plans its own motion:\n```python\n", 1)[1].split("```", 1)[0]
    namespace: dict = {}
    exec(compile(code, "docs/plugins.md", "exec"), namespace)  # noqa: S102 (the page's own example)
    env = panda_env
    env.reset()
    env.hold(0.3)
    target = env.object_ids[1]
    result = namespace["Hover"](target=target).execute(env)
    assert result.success, result.failure_reason
    hand, obj = env.ee_pose().pos, env.object_pose(target).pos
    assert np.linalg.norm(hand[:2] - obj[:2]) < 0.01
    assert hand[2] == pytest.approx(env.object_top(target) + 0.12, abs=0.01)
