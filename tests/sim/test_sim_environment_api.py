"""The environment API plugins rely on (``muble.core.environment.Environment``): the tabletop environment provides
every member of it, its answers match the physics, its sensing members read what a measuring primitive needs, and
the docs' example primitive runs on it. (That no built-in plugin reaches past it into ``muble.sim``, and that it
names no built-in primitive, are rules of tests/core/test_core_layering.py.)"""
import inspect
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

import muble
from muble.core.environment import GRAVITY, Environment, EnvironmentNames
from muble.sim.env import TabletopEnv
from muble.stage.table import part_box
from muble_plugins.primitives.measure import weigh
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
        top, height = env.object_top(obj_id), env.world_bbox(obj_id)["z"]
        assert height == pytest.approx(models[obj_id].extents[2], abs=0.002)
        assert top == pytest.approx(height, abs=0.003), f"object {obj_id}: top {top:.4f} m, height {height:.4f} m"
        assert env.touches_support(obj_id), f"object {obj_id} rests on the table"
        assert not env.is_raised(obj_id) and not env.is_lifted(obj_id)
    with pytest.warns(DeprecationWarning, match=r"object_bbox\(\) is deprecated: call Environment\.world_bbox"):
        assert env.object_bbox(0) == env.world_bbox(0)  # the old name of the world box, for one more release
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
    grams = weigh(env)  # the weigh primitive's reading, through this API alone
    assert grams == pytest.approx(models[2].mass * 1000.0, abs=max(1.0, 0.01 * models[2].mass * 1000.0))
    assert env.measurements[2]["weight"] == grams
    world = env.collision_world()
    assert world is env.collision_world()  # built once, re-synced on every call
    assert world.is_valid(env.arm_q())


def test_sim_the_sensing_members_read_the_hand_the_fingers_and_the_load(panda_env, scene_models):
    """What a measuring primitive reads: the load on the wrist less the hand's own weight (nothing with the empty
    hand, the object's weight once lifted), the pads' closing directions and the fingers' contacts with the held
    object, and a callback after every physics step of ``advance``."""
    env = panda_env
    env.reset()
    _, models = scene_models
    env.hold(0.5)
    force, torque = env.load_wrench()
    assert np.linalg.norm(force) < 0.05 and np.linalg.norm(torque) < 0.01  # the empty hand, still: no load
    assert not list(env.finger_contacts(2))
    left = {env.model.geom(n).id for n in env.names.left_pads}
    assert set(np.flatnonzero(env.pad_side == 1)) == left and np.count_nonzero(env.pad_side == 2) > 0
    pick(env, 2, models[2].extents[2])
    axes = env.closing_axes()
    assert axes.shape == (2, 3) and np.allclose(np.linalg.norm(axes, axis=1), 1.0) and np.allclose(axes[0], -axes[1])
    pressed = {0: 0.0, 1: 0.0}
    for side, _contact, push in env.finger_contacts(2):
        pressed[side] += float(push @ axes[side])  # each finger presses the object along its own closing
    assert pressed[0] > 1.0 and pressed[1] > 1.0, pressed
    calls = []
    env.advance(2 * env.control_dt, on_control=lambda k: calls.append(("control", k)),
                on_physics=lambda: calls.append(("physics", env.data.time)))
    physics = [t for kind, t in calls if kind == "physics"]
    assert [c for c in calls if c[0] == "control"] == [("control", 0), ("control", 1)]
    assert len(physics) == 2 * env.n_substeps and np.all(np.diff(physics) > 0)  # every physics step, in order
    env.hold(0.6)
    loads = []
    env.advance(0.2, on_physics=lambda: loads.append(env.load_wrench()[0].copy()))
    assert np.mean(loads, axis=0)[2] / GRAVITY * 1000.0 == pytest.approx(models[2].mass * 1000.0, rel=0.01)


def test_sim_an_environment_reading_of_the_old_api_forwards_to_the_primitive_with_a_warning(panda_env, scene_models):
    """``env.weigh()`` (the API before the readings moved into the primitives) still reads, as the primitive's
    reading does, and warns with the new name; a name that is no reading is no attribute."""
    env = panda_env
    env.reset()
    _, models = scene_models
    pick(env, 2, models[2].extents[2])
    before = env.snapshot()
    expected = weigh(env)
    env.restore(before)
    env.measurements.clear()
    with pytest.warns(DeprecationWarning, match=r"Environment\.weigh\(\) is deprecated.*"
                                                r"muble_plugins\.primitives\.measure\.weigh\(env, \.\.\.\)"):
        grams = env.weigh()
    assert grams == expected and env.measurements[2]["weight"] == expected
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for name in ("move", "no_such_reading", "_private"):  # a primitive without a reading, no primitive at all
            with pytest.raises(AttributeError):
                getattr(env, name)


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


def test_sim_the_docs_measuring_primitive_reads_through_the_sensing_api(panda_env, scene_models):
    """docs/plugins.md's ``Heft`` example, a measuring primitive written against the environment API alone, as a
    package would write one: it fails with nothing lifted, and reads the lifted object's weight in newtons."""
    text = (PLUGINS.parent / "docs" / "plugins.md").read_text()
    code = text.split("A primitive that measures:", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    namespace: dict = {}
    exec(compile(code, "docs/plugins.md", "exec"), namespace)  # noqa: S102 (the page's own example)
    env = panda_env
    env.reset()
    _, models = scene_models
    assert not namespace["Heft"]().execute(env).success
    pick(env, 2, models[2].extents[2])
    result = namespace["Heft"]().execute(env)
    assert result.success, result.failure_reason
    assert result.measurement == pytest.approx(models[2].mass * GRAVITY, rel=0.01)
    assert env.measurements[2]["heft"] == result.measurement
