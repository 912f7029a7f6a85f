"""The stage generated scenes stand on: the original release's by default (its desk, the Panda standing on it with a
Robotiq 85), robosuite's in protocol shopvrb2_v1 and with generator.stage=robosuite (its scene files name no stage and
keep the bytes they had before stages could be chosen). generator.stage is the one setting: the robot has none, and
an episode stands on the stage its scene file names."""
from __future__ import annotations

import numpy as np
import pytest
from omegaconf import OmegaConf

from muble import Outcome, get_registry
from muble.app.config import compose
from muble.generation import SceneGenerator
from muble.io.scene_io import scene_to_dict
from tests.generation.builtin import BUILTIN

pytestmark = pytest.mark.gl


def test_scenes_default_to_the_original_stage_and_the_protocol_pins_robosuites():
    assert compose("generate", ["dataset.root=/tmp"]).generator.stage == "original"
    assert compose("run", ["dataset.root=/tmp"]).generator.stage == "original"
    assert compose("generate", ["dataset.root=/tmp", "protocol=shopvrb2_v1"]).generator.stage == "robosuite"
    # The protocol names its stage itself, so it keeps it whatever the generator's default.
    from importlib import resources

    protocol = OmegaConf.create((resources.files("muble_conf") / "protocol" / "shopvrb2_v1.yaml").read_text())
    assert protocol.generator.stage == "robosuite"


def test_the_generator_alone_names_the_stage(object_set):
    from hydra.errors import ConfigCompositionException

    with pytest.raises(ConfigCompositionException, match="stage"):
        compose("generate", ["dataset.root=/tmp", "robot.stage=original"])
    cfg = compose("generate", ["dataset.root=/tmp", "generator.stage=robosuite"])
    generator = SceneGenerator(OmegaConf.to_container(cfg.generator, resolve=True), object_set=object_set)
    try:
        assert generator.config.stage == "robosuite" and list(generator.config.table_y) == [-0.6, 0.6]
    finally:
        generator.close()


def test_robosuite_stage_scenes_are_the_scenes_made_before_stages(object_set):
    """A generator without a stage (as before stages could be chosen) and one on robosuite's stage write the same
    scene, naming no stage."""
    scenes = []
    for options in ({}, {"stage": "robosuite"}):
        generator = SceneGenerator({**BUILTIN, **options}, seed=4, object_set=object_set)
        try:
            scenes.append(scene_to_dict(generator.generate(0)))
        finally:
            generator.close()
    assert "stage" not in scenes[0] and scenes[0] == scenes[1]


def test_a_scene_generated_on_the_original_stage_names_it_and_the_oracle_solves_it():
    """`muble run`'s generator with generator.stage=original: the scene file names the stage, its environment is
    built there with the Robotiq 85 (robot.gripper left unset), and the oracle weighs an object on
    it with physics."""
    from muble.episode.components import episode_runner, scene_generator
    from muble.evaluation.episodes import build_components
    from muble.sim.build import env_from_object_set

    cfg = compose("eval", ["seed=3", "agent=oracle", "output.dir=/tmp", "dataset.root=/tmp",
                           "generator.stage=original"])
    components = build_components(OmegaConf.to_container(cfg, resolve=True))
    generator = scene_generator(cfg, components["object_set"])
    try:
        scene = generator.generate(0)
    finally:
        generator.close()
    assert scene.extra["stage"] == "original"
    assert scene_to_dict(scene)["stage"] == "original"  # written into the file
    env = env_from_object_set(scene, components["object_set"], visual=False)
    try:
        assert env.names.stage == "original" and env.names.gripper_format.__class__.__name__ == "Robotiq85Gripper"
    finally:
        env.close()
    task = get_registry().create("task", "measure_weight_single", {})
    instruction = task.generate(scene, np.random.default_rng([3, 0, 1]))[0]
    result = episode_runner(cfg, components).execute(scene, instruction, task).result
    assert result.outcome is Outcome.SUCCESS, (instruction.instruction, [str(a) for a in result.actions], result.error)
