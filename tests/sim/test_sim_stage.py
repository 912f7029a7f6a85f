"""Stages: where the table and the robot stand. The original release's files are built on its own stage (its desk,
the Panda standing on it without a mount, a Robotiq 85, its rest pose); generated scenes on the one they name."""
import copy

import mujoco
import numpy as np
import pytest

from muble.core.errors import ConfigError
from muble.sim.env import TabletopEnv
from muble.sim.world import scene_stage
from muble.stage.table import STAGES
from tests.support.scenes import five_object_scene

ORIGINAL_REST = [0.0, 0.0, 0.0, -0.75 * np.pi, 0.0, 0.75 * np.pi, 0.25 * np.pi]


@pytest.fixture(scope="module")
def scene_models():
    return five_object_scene()


def _as_original_release(scene):
    """The scene as the original release writes it: every object at its import scale (0.6 or 0.45)."""
    scene = copy.deepcopy(scene)
    for obj in scene.objects:
        obj.scale_factor = 0.6
    return scene


def _table(env):
    geom = env.model.geom("table_collision")
    data = mujoco.MjData(env.model)
    mujoco.mj_forward(env.model, data)
    return data.geom_xpos[geom.id].copy(), env.model.geom_size[geom.id].copy()


def test_original_release_scenes_stand_on_the_original_desk(scene_models):
    scene, models = scene_models
    env = TabletopEnv(_as_original_release(scene), models)
    assert env.names.stage == "original"
    centre, half = _table(env)
    # 1.36 x 0.8 m, 2.6 cm thick, its back edge 0.23 m behind the robot's base axis, its top at z = 0
    np.testing.assert_allclose(half, [0.68, 0.4, 0.013], atol=1e-9)
    np.testing.assert_allclose(centre + [0, 0, half[2]], [0.45, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(centre[0] - half[0], -0.23, atol=1e-9)
    data = mujoco.MjData(env.model)
    mujoco.mj_forward(env.model, data)
    np.testing.assert_allclose(data.xpos[env.model.body("robot0_link0").id], [0, 0, 0], atol=1e-9)
    assert type(env.names.gripper_format).__name__ == "Robotiq85Gripper"
    # the rest pose is the original's, kept as its frames show it (not raised like robosuite's)
    np.testing.assert_allclose(env.names.init_qpos, ORIGINAL_REST, atol=1e-9)
    np.testing.assert_allclose(env.data.qpos[[env.model.jnt_qposadr[env.model.joint(j).id]
                                              for j in env.names.arm_joints]], ORIGINAL_REST, atol=1e-6)
    # no pedestal: nothing of a mount is drawn
    mount = [env.model.geom(i).name for i in range(env.model.ngeom) if env.model.geom(i).name.startswith("mount0_")
             and env.model.geom_rgba[i][3] > 0]
    assert mount == []


def test_generated_scenes_keep_robosuite_stage_and_a_named_stage_wins(scene_models):
    scene, models = scene_models
    env = TabletopEnv(scene, models)
    assert env.names.stage == "robosuite"
    centre, half = _table(env)
    np.testing.assert_allclose(2 * half, STAGES["robosuite"].table_size, atol=1e-9)
    assert type(env.names.gripper_format).__name__ == "PandaGripper"

    named = copy.deepcopy(scene)
    named.extra["stage"] = "original"
    assert scene_stage(named).name == "original"
    assert scene_stage(named, "robosuite").name == "robosuite"  # robot.stage overrides the file
    forced = TabletopEnv(_as_original_release(scene), models, stage="robosuite", visual=False)
    assert forced.names.stage == "robosuite"
    # a gripper asked for wins over the stage's
    env = TabletopEnv(named, models, gripper="PandaGripper", visual=False)
    assert type(env.names.gripper_format).__name__ == "PandaGripper"


def test_unknown_stages_are_named_with_the_valid_ones(scene_models):
    scene, models = scene_models
    with pytest.raises(ConfigError, match=r"unknown stage 'studio'.*original, robosuite \(from robot.stage\)"):
        TabletopEnv(scene, models, stage="studio", visual=False)
    bad = copy.deepcopy(scene)
    bad.extra["stage"] = "moon"
    with pytest.raises(ConfigError, match="moon.*robot.stage"):
        scene_stage(bad)


def test_the_original_stage_grasps_and_lifts_with_its_robotiq(scene_models):
    """The oracle's pick works on the original stage: an object rises with the hand and the weight is measured."""
    from muble_plugins.primitives.measure import weigh
    from tests.sim.conftest import pick

    scene, models = scene_models
    env = TabletopEnv(scene, models, stage="original")
    target = scene.objects[0]
    start = env.object_pose(target.id).pos.copy()
    pick(env, target.id, models[target.id].extents[2])
    assert env.held_object == target.id
    assert env.object_pose(target.id).pos[2] > start[2] + 0.08
    assert weigh(env) == pytest.approx(target.weight_gt, abs=max(1.0, 0.01 * target.weight_gt))


@pytest.mark.parametrize("stage", sorted(STAGES))
def test_both_worlds_place_within_the_same_table_top_on_every_stage(scene_models, stage):
    """The symbolic world (scene graph only) and the physical one (the compiled table) keep a part's places inside
    the same top: on the original release's narrower desk a place the symbolic world chose off its left edge was
    one the arm could never put an object on, and episodes asking for it failed."""
    from muble.core.types import TABLE_PARTS
    from muble.stage.footprint import free_spot
    from muble.stage.table import part_box, scene_part_region, stage_of

    scene, models = scene_models
    scene = copy.deepcopy(scene)
    scene.extra["stage"] = stage
    env = TabletopEnv(scene, models)
    try:
        table = env.table()
        np.testing.assert_allclose(np.array(STAGES[stage].top).T, [table.centre - table.half, table.centre + table.half],
                                   atol=1e-9)
        assert stage_of(scene) is STAGES[stage]
        for part in TABLE_PARTS:
            lo, hi = part_box(env, part)
            np.testing.assert_allclose(np.array(scene_part_region(scene, part)).T, [lo, hi], atol=1e-9)
        # Where the symbolic world puts an object down on the left lies in the physical world's region.
        lo, hi = part_box(env, "left")
        spot = free_spot(scene, scene.objects[0], "left")
        assert spot is not None and lo[0] <= spot[0] <= hi[0] and lo[1] <= spot[1] <= hi[1]
    finally:
        env.close()


def test_the_original_desk_narrows_the_left_part_and_robosuite_table_leaves_the_parts_as_they_were():
    from muble.core.types import TABLE_PARTS
    from muble.stage.table import part_region

    robosuite, original = STAGES["robosuite"], STAGES["original"]
    for part in TABLE_PARTS:
        assert robosuite.part_region(part) == part_region(part, robosuite.place)
    (_, _), (y0, _) = original.part_region("left")
    assert y0 == pytest.approx(-0.4 + 0.08) and robosuite.part_region("left")[1][0] == pytest.approx(-0.40)
