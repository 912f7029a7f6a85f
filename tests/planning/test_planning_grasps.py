"""Grasp frames of the SHOP-VRB2 set and real picks of the categories they are hardest for."""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

from muble import get_registry
from muble.core.types import Pose

from muble_plugins.objects.catalogue import SIZE_SCALES
from muble_plugins.objects.shopvrb2 import CATALOGUE
from muble_plugins.primitives.grasping import grasp_candidates, measure_grip
from tests.generation.builtin import BUILTIN

PANDA_GAP = 0.0768  # m between the open Panda pads
# Gap between the open pads' inner faces: Panda hand 80 mm stroke, Robotiq 2F-85 85 mm, Rethink electric gripper
# with robosuite's finger travel about 62 mm.
OPEN_GAPS = {"Panda": (0.072, 0.082), "UR5e": (0.080, 0.090), "Sawyer": (0.056, 0.066)}


def _axes(quat):
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, float))
    return rot.reshape(3, 3)


@pytest.fixture(scope="module")
def objects():
    return get_registry().create("object_set", "shopvrb2", {"cache_dir": None})


def test_planning_every_pickupable_model_has_a_grasp_that_fits_the_open_gripper(objects):
    rng = np.random.default_rng(0)
    for category in objects.categories():
        spec = objects.sample(rng, category=category)
        if not objects.build(spec).pickupable:
            continue
        for model in objects.models(category):
            for size in CATALOGUE[category].sizes:
                spec.model, spec.size, spec.scale = model, size, SIZE_SCALES[size]
                built = objects.build(spec)
                widths = [f.width for f in built.grasp_frames]
                assert min(widths) < PANDA_GAP - 0.004, (model, size, widths)  # 2 mm to spare each side


def test_planning_rim_pinches_close_across_the_wall_and_candidates_keep_that(objects):
    spec = objects.sample(np.random.default_rng(1), category="bowl")
    model = objects.build(spec)
    for frame in model.grasp_frames:
        closing, approach = _axes(frame.quat)[:, 0], _axes(frame.quat)[:, 2]
        closing[2] = 0.0  # a flared wall tilts the fingers with it; across the wall is the horizontal part
        radial = np.array([frame.position[0], frame.position[1], 0.0])
        assert abs(closing @ radial) / (np.linalg.norm(closing) * np.linalg.norm(radial)) > 0.99
        assert approach[2] < -0.8  # from above
    pose = Pose(np.array([0.5, 0.1, 0.0]), np.array([np.cos(0.3), 0.0, 0.0, np.sin(0.3)]))
    candidates = grasp_candidates(pose, model, 0.0, max_width=0.07)
    assert len(candidates) == 2 * len(model.grasp_frames)
    for c in candidates:
        radial = c.pos - pose.pos
        radial[2] = 0.0
        closing = _axes(c.quat)[:, 0]
        closing[2] = 0.0
        assert abs(closing @ radial) / (np.linalg.norm(closing) * np.linalg.norm(radial)) > 0.99


def test_planning_frames_too_wide_for_the_fingers_are_left_out(objects):
    spec = objects.sample(np.random.default_rng(2), category="glass")
    spec.model, spec.size, spec.scale = "glass3", "large", 1.15
    model = objects.build(spec)
    candidates = grasp_candidates(Pose(np.zeros(3), np.array([1.0, 0, 0, 0])), model, 0.0, max_width=0.07)
    assert candidates  # the rim is still there
    assert all(np.hypot(*c.pos[:2]) > 0.02 for c in candidates)  # but not the 9 cm body


@pytest.mark.slow
@pytest.mark.gl
def test_planning_pick_and_weigh_wine_glasses_mugs_and_glasses_in_a_generated_scene():
    from muble.generation.generator import SceneGenerator
    from muble.sim.build import env_from_object_set

    generator = SceneGenerator({**BUILTIN, "masks": False, "object_set": "shopvrb2",
                                "object_set_options": {"categories": ["wine glass", "mug", "glass"]}}, seed=3)
    scene = generator.generate(0)
    env = env_from_object_set(scene, "shopvrb2")
    try:
        for obj in scene.objects:
            env.reset()
            for name, params in [("approach", {"target": obj.id}), ("close_gripper", {}), ("lift", {})]:
                result = get_registry().create("primitive", name, params).execute(env)
                assert result.success, (obj.model, name, result.failure_reason)
                assert not result.info.get("unintended_contacts"), (obj.model, name, result.info)
            assert env.held_object == obj.id
            grams = get_registry().create("primitive", "weigh", {}).execute(env).measurement
            assert abs(grams - obj.weight_gt) < 0.01 * obj.weight_gt, (obj.model, grams, obj.weight_gt)
    finally:
        env.close()
        generator.close()


@pytest.mark.parametrize("robot", sorted(OPEN_GAPS))
def test_planning_grip_geometry_comes_from_the_mounted_gripper(robot):
    from muble.sim.env import TabletopEnv
    from tests.support.scenes import five_object_scene

    scene, models = five_object_scene()
    env = TabletopEnv(scene, models, name=robot)
    grip = measure_grip(env)
    lo, hi = OPEN_GAPS[robot]
    assert lo < grip.open_gap < hi
    assert grip.closed_gap < 0.02 < grip.max_width
    assert abs(grip.closing[0]) > 0.99 and abs(grip.closing @ grip.approach) < 1e-9  # robosuite: across site x
    # A grasp frame puts the pads' middle on the frame's origin, closing along its x, approaching along its z.
    frame = Pose(np.array([0.5, 0.1, 0.05]), np.array([0.0, 1.0, 0.0, 0.0]))  # from above, closing along world x
    for width in (0.01, 0.06):
        site = grip.site_pose(frame, width)
        rot = _axes(site.quat)
        np.testing.assert_allclose(site.pos + rot @ grip.centre(width), frame.pos, atol=1e-9)
        np.testing.assert_allclose(rot @ grip.closing, [1.0, 0.0, 0.0], atol=1e-9)
        np.testing.assert_allclose(rot @ grip.approach, [0.0, 0.0, -1.0], atol=1e-9)


def test_planning_grip_geometry_is_the_same_whatever_state_or_scene_it_is_measured_in():
    """The measured pad geometry is cached per process: it must not depend on the scene or on where the arm and
    fingers were when it was first measured, or an episode's outcome would depend on the episodes before it."""
    import dataclasses

    from muble.sim.env import TabletopEnv
    from tests.support.scenes import five_object_scene, simple_scene

    scene, models = five_object_scene()
    first = TabletopEnv(scene, models)
    second = TabletopEnv(simple_scene([(0.45, 0.1)], [models[2]]), {0: models[2]})
    second.data.qpos[second.arm_qpos_adr] += 0.3  # the arm elsewhere, the hand closed
    second.set_arm_target(second.arm_q())
    second.close_gripper()
    second.hold(0.3)
    a, b = measure_grip(first), measure_grip(second)
    for field in dataclasses.fields(a):
        np.testing.assert_array_equal(getattr(a, field.name), getattr(b, field.name), err_msg=field.name)


@pytest.mark.slow
def test_planning_ur5e_with_its_robotiq_gripper_picks_and_weighs_a_can_a_thermos_and_a_bowl(objects):
    from muble.sim.env import TabletopEnv
    from tests.support.scenes import simple_scene

    rng = np.random.default_rng(0)
    models = [objects.build(objects.sample(rng, category=c)) for c in ("soda can", "thermos", "bowl")]
    env = TabletopEnv(simple_scene([(0.40, -0.25), (0.42, 0.0), (0.62, 0.05)], models), dict(enumerate(models)),
                      name="UR5e")
    try:
        for obj_id, model in enumerate(models):
            env.reset()
            for name, params in [("approach", {"target": obj_id}), ("close_gripper", {}), ("lift", {})]:
                result = get_registry().create("primitive", name, params).execute(env)
                assert result.success, (model.spec.model, name, result.failure_reason)
            assert env.held_object == obj_id
            assert env.object_pose(obj_id).pos[2] > 0.1
            grams = get_registry().create("primitive", "weigh", {}).execute(env).measurement
            assert abs(grams - model.spec.weight_g) < 0.01 * model.spec.weight_g, (model.spec.model, grams)
    finally:
        env.close()


@pytest.mark.slow
def test_planning_mug_hemmed_in_by_wine_glasses_is_grasped_from_above_it_with_the_hand_part_open():
    """A mug 9 cm from a wine glass, its handle towards another: from the hover pose over it, every rim grasp with
    the fully open hand touches a glass or the mug's own handle; the hand opened part way fits and holds it."""
    from pathlib import Path

    from muble.io.scene_io import load_scene
    from muble.sim.build import env_from_object_set

    scene = load_scene(Path(__file__).parent / "data" / "mug_handle_between_wine_glasses.json")
    mug = next(o for o in scene.objects if o.name == "mug")
    env = env_from_object_set(scene, "shopvrb2")
    try:
        for name, params in [("move", {"target": mug.id}), ("approach", {"target": mug.id}), ("close_gripper", {}),
                             ("lift", {})]:
            result = get_registry().create("primitive", name, params).execute(env)
            assert result.success, (name, result.failure_reason)
            assert not result.info.get("unintended_contacts"), (name, result.info)
        assert env.held_object == mug.id
        grams = get_registry().create("primitive", "weigh", {}).execute(env).measurement
        assert abs(grams - mug.weight_gt) < 0.01 * mug.weight_gt
    finally:
        env.close()
