"""Friction, centre of mass and loose contents: modelled in the MJCF from an object model's values (an object
without them builds the MJCF it always did) and measured by the ``push``, ``balance`` and ``shake`` primitives
through real physics (docs/physical_properties.md)."""
from __future__ import annotations

import dataclasses
import hashlib

import mujoco
import numpy as np
import pytest

from muble import SceneValidationError, get_registry
from muble.core import physical_properties
from muble.core.objects import GraspFrame, MeshPart, ObjectModel, ObjectSpec
from muble.core.symbolic import set_flag
from muble.sim.build import object_models
from muble.sim.env import TabletopEnv
from muble.sim.object_mjcf import CONTENTS_COLLISION_CLASS, FRICTION_PRIORITY, object_mjcf, test_world_xml
from tests.support.scenes import simple_scene

# sha256 of the asset and body MJCF of ``_box()`` as object 2 at (0.5, 0.1, 0), written before the hidden
# properties existed: an object that gives none of them must build exactly these bytes.
DEFAULT_MJCF_SHA256 = "a14da05245f9485d7d17ac8430e902f5899184ee9a8229c16321baf6547818d7"


def _box(**changes) -> ObjectModel:
    """A 6 × 4 × 8 cm, 250 g box with an explicit mesh (no mesh library involved)."""
    v = np.array([[x, y, z] for x in (-0.03, 0.03) for y in (-0.02, 0.02) for z in (0.0, 0.08)])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                  [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    part = MeshPart(v, f)
    spec = ObjectSpec("test", "food box", "box", "red", "plastic", "medium-sized", "cuboid", 1.0, 250.0, 12000.0, 0.6)
    model = ObjectModel(spec=spec, visual=part, collision_parts=[part], mass=0.25, com=np.array([0.0, 0.0, 0.04]),
                        inertia=np.diag([1.6e-4, 2.1e-4, 1.1e-4]), friction=0.6, stiffness=12000.0, damping=30.0,
                        rgba=(0.8, 0.1, 0.1, 1.0), material_class="plastic", grasp_type="box",
                        grasp_frames=[GraspFrame(np.array([0.0, 0.0, 0.06]), np.array([0.0, 1.0, 0.0, 0.0]), 0.04)],
                        pickupable=True, stackable=True, stack_base=True, extents=np.array([0.06, 0.04, 0.08]))
    return dataclasses.replace(model, **changes)


def _world(model: ObjectModel) -> tuple[mujoco.MjModel, mujoco.MjData]:
    m = mujoco.MjModel.from_xml_string(test_world_xml([(model, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))]))
    return m, mujoco.MjData(m)


def test_sim_an_object_without_hidden_properties_builds_the_mjcf_it_always_did():
    mjcf = object_mjcf(_box(), 2, (0.5, 0.1, 0.0))
    assert hashlib.sha256((mjcf.asset_xml + mjcf.body_xml).encode()).hexdigest() == DEFAULT_MJCF_SHA256
    assert "priority" not in mjcf.body_xml and "_contents" not in mjcf.body_xml and "_wall" not in mjcf.body_xml


def test_sim_the_objects_own_friction_decides_its_contact_with_the_table():
    for model, expected in ((_box(), 1.0), (_box(friction_coefficient=0.35), 0.35)):
        m, d = _world(model)
        mujoco.mj_step(m, d, nstep=50)
        table = m.geom("table").id
        frictions = {round(float(c.friction[0]), 6) for c in d.contact[:d.ncon] if table in c.geom}
        # without it MuJoCo takes the larger of the two geoms' (the table's 1); with it, the object's priority wins
        assert frictions == {expected}, (model.friction_coefficient, frictions)
    m, _ = _world(_box(friction_coefficient=0.35))
    assert m.geom_priority[m.geom("obj0_col0").id] == FRICTION_PRIORITY > m.geom_priority[m.geom("table").id]


def test_sim_a_centre_of_mass_offset_moves_the_inertial_position_only():
    m, _ = _world(_box(com_offset=[0.012, -0.007]))
    body = m.body("obj0").id
    np.testing.assert_allclose(m.body_ipos[body], [0.012, -0.007, 0.04], atol=1e-9)
    assert m.body_mass[body] == pytest.approx(0.25)
    m, _ = _world(_box(com_offset=[0.0, 0.0, -0.01]))
    np.testing.assert_allclose(m.body_ipos[m.body("obj0").id], [0.0, 0.0, 0.03], atol=1e-9)


def test_sim_loose_contents_rest_inside_walls_and_the_object_keeps_its_weight():
    with pytest.raises(ValueError, match="no closed container"):
        object_mjcf(_box(contents_mass=0.03), 0)
    model = _box(closed=True, contents_mass=0.03)
    m, d = _world(model)
    box, ball = m.body("obj0").id, m.body("obj0_contents").id
    assert m.body_mass[box] + m.body_mass[ball] == pytest.approx(0.25)
    assert m.body_mass[ball] == pytest.approx(0.03)
    inside = [g for g in range(m.ngeom) if m.geom_contype[g] == CONTENTS_COLLISION_CLASS]
    assert {m.geom(g).name for g in inside} == {"obj0_contents_col", *(f"obj0_wall{k}" for k in range(6))}
    assert all(m.geom_conaffinity[g] == CONTENTS_COLLISION_CLASS and m.geom_group[g] == 3 for g in inside)
    mujoco.mj_step(m, d, nstep=500)  # 1 s: the box settles on the table, the ball on the cavity's floor
    touched = {frozenset((int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]]))) for c in d.contact[:d.ncon]}
    assert frozenset((box, ball)) in touched  # the ball rests on the walls ...
    assert all(ball not in pair or pair == frozenset((box, ball)) for pair in touched)  # ... and on nothing else
    ball_in_box = d.xmat[box].reshape(3, 3).T @ (d.xpos[ball] - d.xpos[box])
    assert np.all(np.abs(ball_in_box[:2]) < [0.03, 0.02]) and 0.0 < ball_in_box[2] < 0.08
    assert abs(d.xpos[box][2]) < 0.002  # standing on the table top


def test_sim_scene_values_build_into_the_object_model(object_set):
    scene = simple_scene([(0.5, 0.0), (0.5, 0.2)], [_box(), _box()])
    can = object_set.sample(np.random.default_rng(3), "soda can")
    for obj in scene.objects:  # catalogue objects, so that one of them is a closed container
        obj.name, obj.model, obj.material, obj.shape, obj.size = (can.category, can.model, can.material, can.shape,
                                                                  can.size)
        obj.weight_gt, obj.scale_factor = can.weight_g, can.scale
    scene.objects[0].extra.update({physical_properties.FRICTION: 0.4, physical_properties.COM_OFFSET: [0.01, 0.0],
                                   physical_properties.CONTENTS: 25.0})
    models = object_models(scene, object_set, "shopvrb2")
    assert models[0].friction_coefficient == 0.4 and models[0].contents_mass == pytest.approx(0.025)
    assert list(models[0].com_offset) == [0.01, 0.0]
    plain = models[1]
    assert plain.friction_coefficient is None and plain.com_offset is None and plain.contents_mass == 0.0
    scene.objects[1].extra[physical_properties.FRICTION] = -0.2
    with pytest.raises(SceneValidationError, match="friction_coefficient"):
        object_models(scene, object_set, "shopvrb2")
    scene.objects[1].extra[physical_properties.FRICTION] = 0.5
    scene.objects[1].name, scene.objects[1].model = "mug", "mug1"  # an open vessel holds no loose contents
    scene.objects[1].extra[physical_properties.CONTENTS] = 10.0
    with pytest.raises(SceneValidationError, match="no closed container"):
        object_models(scene, object_set, "shopvrb2")


# ------------------------------------------------------------------------------------------------ measuring
def _act(env, name, **params):
    return get_registry().create("primitive", name, params).execute(env)


def _picked(model: ObjectModel, gripper: str | None = None, lift: bool = True) -> TabletopEnv:
    """``model`` alone on the table, grasped by the primitives (and lifted)."""
    env = TabletopEnv(simple_scene([(0.5, 0.05)], [model]), {0: model}, visual=False,
                      **({"gripper": gripper} if gripper else {}))
    env.planner = get_registry().create("planner", "ompl", {})
    steps = [("move", {"target": 0}), ("approach", {"target": 0}), ("close_gripper", {"target": 0})]
    for name, params in steps + ([("lift", {})] if lift else []):
        result = _act(env, name, **params)
        assert result.success, (name, result.failure_reason)
    return env


def _sampled(object_set, category: str, seed: int, **changes) -> ObjectModel:
    return dataclasses.replace(object_set.build(object_set.sample(np.random.default_rng(seed), category)), **changes)


def test_sim_push_reads_the_friction_coefficient_weighing_first_where_no_weight_is_known(object_set):
    """The agent's way: grasp it standing, push (weighed in the hand first, not recorded as a weighing); then with
    its weight measured in the episode, with a linkage gripper, and a retry that pushes another way, slower."""
    mug = _sampled(object_set, "mug", 1, friction_coefficient=0.85)
    env = _picked(mug, lift=False)
    result = _act(env, "push")
    assert result.success, result.failure_reason
    assert result.measurement == pytest.approx(0.85, rel=0.1)
    assert env.measurements[0] == {"friction": result.measurement}  # the push's own weighing serves it only
    assert not env.is_lifted(0) and env.held_object == 0  # set down where it stood, still in the hand
    can = _sampled(object_set, "soda can", 2, friction_coefficient=0.4)
    env = _picked(can, "Robotiq85Gripper", lift=False)
    standing = env.snapshot()
    assert _act(env, "lift").success and _act(env, "weigh").success
    env.restore(standing)  # held where it stands again, its weight measured
    result = _act(env, "push", direction=[1.0, 0.0], distance=0.06)
    assert result.success, result.failure_reason
    assert result.measurement == pytest.approx(0.4, rel=0.1)
    assert result.info["direction"] == [1.0, 0.0]
    env.restore(standing)
    retried = _act(env, "push", attempt=1)
    assert retried.success and retried.info["direction"] != [0.0, 1.0]  # not the first of DIRECTIONS
    assert retried.measurement == pytest.approx(0.4, rel=0.1)


def test_sim_a_push_that_loses_the_object_fails_and_leaves_no_friction_reading(object_set):
    """The fingers open half-way through the first stroke (a disturbance, run after every control step): the
    wrist is still read over the steady stretch of both strokes, so the reading has a finite coefficient, but the
    object is no longer in the hand. The push fails, and no friction coefficient is left in the measurements."""
    mug = _sampled(object_set, "mug", 1, friction_coefficient=0.85)
    env = _picked(mug, lift=False)
    start = env.ee_pose().pos.copy()

    def let_go(e):
        if e.held_object is not None and np.linalg.norm(e.ee_pose().pos[:2] - start[:2]) > 0.04:
            e.open_gripper()

    env.control_listeners.append(let_go)
    result = _act(env, "push", direction=[0.0, 1.0])
    assert not result.success and "slipped out of the hand" in result.failure_reason, result
    # A reading was taken (the hand pushed along the table, which carried the weight), and is left unrecorded.
    assert result.info["samples"] > 0 and result.info["normal_force"] > 0, result.info
    assert "friction" not in env.measurements.get(0, {}), env.measurements
    assert "friction_measured" not in env.sync_scene_graph().object(0).extra


@pytest.mark.parametrize("category, gripper", [("glass", None), ("bowl", "Robotiq85Gripper")])
def test_sim_balance_reads_the_centre_of_mass(object_set, category, gripper):
    offset = np.array([0.011, -0.017]) if category == "bowl" else np.array([-0.008, 0.006])
    env = _picked(_sampled(object_set, category, 4, com_offset=offset), gripper)
    result = _act(env, "balance")
    assert result.success, result.failure_reason
    np.testing.assert_allclose(result.measurement, offset * 1000.0, atol=1.0)  # mm


def test_sim_shake_hears_loose_contents_and_not_a_solid_can(object_set):
    for grams in (0.0, 15.0):
        env = _picked(_sampled(object_set, "soda can", 5, contents_mass=grams / 1000.0))
        weighed = _act(env, "weigh").measurement
        assert weighed == pytest.approx(env.object_models[0].mass * 1000.0, abs=1.0)  # the contents weigh too
        result = _act(env, "shake")
        assert result.success, result.failure_reason
        assert result.measurement is (grams > 0), result.info



def test_sim_a_shake_that_loses_the_object_fails_and_leaves_no_rattle_reading(object_set):
    """The fingers open during the swings (a disturbance, run after every control step): the wrist was read, so a
    reading exists, but the object is no longer in the hand. The shake fails, and nothing says whether it
    rattles (as for push: a reading counts only when the primitive succeeded)."""
    env = _picked(_sampled(object_set, "soda can", 5, contents_mass=0.015))
    steps = []

    def let_go(e):
        steps.append(1)
        if len(steps) == 10 and e.held_object is not None:
            e.open_gripper()

    env.control_listeners.append(let_go)
    result = _act(env, "shake")
    assert len(steps) > 10, steps  # the swings ran past the moment the hand opened
    assert not result.success and "slipped out of the hand" in result.failure_reason, result
    assert "peak_force" in result.info, result.info
    assert "rattles" not in env.measurements.get(0, {}), env.measurements
    assert "rattles_measured" not in env.sync_scene_graph().object(0).extra

def test_sim_probing_primitives_have_symbolic_effects():
    scene = simple_scene([(0.5, 0.0)], [_box()])
    obj = scene.objects[0]
    obj.extra.update({physical_properties.FRICTION: 0.7, physical_properties.COM_OFFSET: [0.004, -0.002]})
    set_flag(scene, "in_hand", obj)
    registry = get_registry()

    def effect(name):
        return registry.create("primitive", name, {}).symbolic_effect(scene)

    assert effect("push").measurement == 0.7  # no weighing needed first: push weighs in the hand
    assert not effect("balance").success  # standing on the table: lift it first
    obj.extra["raised"] = True
    assert effect("balance").measurement == pytest.approx([4.0, -2.0])
    assert effect("shake").measurement is False
    obj.extra[physical_properties.CONTENTS] = 12.0
    assert effect("shake").measurement is True
    assert not effect("push").success  # lifted: it no longer stands on the table


def test_sim_a_container_with_contents_is_as_tall_and_as_heavy_as_without(object_set):
    """The cavity's walls and ball sit inside: the object's top, weight on the table and planning are unchanged."""
    solid = _sampled(object_set, "soda can", 6)
    tops = []
    for model in (solid, dataclasses.replace(solid, contents_mass=0.02)):
        env = TabletopEnv(simple_scene([(0.5, 0.05)], [model]), {0: model}, visual=False)
        env.hold(0.5)
        tops.append(env.object_top(0))
        assert env.collision_world().is_valid(env.arm_q())
    assert tops[1] == pytest.approx(tops[0], abs=1e-4)


def test_sim_a_loose_ball_spinning_fast_is_no_physics_fault_but_a_runaway_one_is(object_set):
    """A can that falls over knocks its 1 cm ball to 100 rad/s and more (1 m/s at its surface): the fault detector
    holds a ball's turning to the speed limit at its surface, everything else as before."""
    import mujoco

    from muble.core.errors import PhysicsError

    can = _sampled(object_set, "soda can", 5, contents_mass=0.02)
    env = TabletopEnv(simple_scene([(0.5, 0.05)], [can]), {0: can}, visual=False)
    m, d = env.model, env.data
    ball = m.jnt_dofadr[m.joint("obj0_contents_joint").id]
    can_dof = m.jnt_dofadr[[j for j in range(m.njnt) if m.jnt_bodyid[j] == m.body("obj0").id][0]]
    d.qvel[ball + 3:ball + 6] = [0.0, 120.0, 0.0]
    env.faults.check(d)  # 120 rad/s of a ball of at most 1 cm: 1.2 m/s at its surface
    d.qvel[ball:ball + 3] = [60.0, 0.0, 0.0]
    with pytest.raises(PhysicsError, match="unstable"):
        env.faults.check(d)
    mujoco.mj_resetData(m, d)
    d.qvel[can_dof + 3:can_dof + 6] = [0.0, 120.0, 0.0]  # the can itself turning that fast is a fault
    with pytest.raises(PhysicsError, match="unstable"):
        env.faults.check(d)
