"""The Gymnasium environments: registered ids, the env checker, seeded resets, the action text's shapes."""
from __future__ import annotations

import json
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import muble.gym  # noqa: F401 - registers the ids
from muble.core.errors import ConfigError
from muble.core.types import ActionCall, Answer
from muble.gym.shopvrb2 import MalformedAction, parse_action

SMALL = ["renderer.width=32", "renderer.height=24"]


def test_ids_are_registered():
    assert {"MuBlE/ShopVRB2-v0", "MuBlE/Tabletop-v0"} <= set(gymnasium.envs.registry)



def _check_env_quietly(env):
    """Gymnasium's env checker on the unwrapped environment (its advisory warnings ignored)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env.unwrapped, skip_render_check=True)

@pytest.mark.parametrize("text, expected", [
    ('{"name": "approach", "params": {"target": 3}}', (ActionCall("approach", {"target": 3}), True)),
    ('{"name": "lift"}', (ActionCall("lift", {}), True)),
    ('{"answer": [12.5]}', (Answer([12.5]), True)),
    ('{"answer": 1, "stop": false}', (Answer(1), False)),
    ('{"stop": true}', (None, True)),
])
def test_action_text_shapes(text, expected):
    assert parse_action(text) == expected


@pytest.mark.parametrize("text", ["", "approach(3)", "[1, 2]", '{"name": 3}', '{"name": "lift", "params": []}',
                                  '{"stop": 1}', '{"answer": 1, "name": "x"}', '{"go": true}'])
def test_malformed_action_text_is_handed_to_the_loop_as_invalid(text):
    decision, _ = parse_action(text)
    assert isinstance(decision, MalformedAction)


@pytest.mark.slow
@pytest.mark.gl
def test_shopvrb2_passes_the_env_checker_and_seeds_deterministically():
    env = gymnasium.make("MuBlE/ShopVRB2-v0", overrides=SMALL, templates=["measure_weight_single"])
    try:
        _check_env_quietly(env)
        first, info = env.reset(seed=7)
        again, info_again = env.reset(seed=7)
        assert first["scene"] == again["scene"] and first["instruction"] == again["instruction"]
        assert info["instruction"] == info_again["instruction"]
        # None of the instruction file's ground-truth records: the actions, the task's target, the sampling.
        assert not {"ground_truth_actions", "task", "scene_samples"} & set(info["instruction"]), info["instruction"]
        assert np.array_equal(first["images"]["front"], again["images"]["front"])
        assert env.observation_space.contains(first)
        assert "weight_gt" not in first["scene"]
        # A call no primitive accepts ends the episode as the agent's fault, as in run_episode.
        _, reward, terminated, truncated, step_info = env.step(json.dumps({"name": "fly", "params": {}}))
        assert (reward, terminated, truncated, step_info["outcome"]) == (0.0, True, False, "invalid_action")
    finally:
        env.close()


@pytest.mark.slow
@pytest.mark.gl
def test_tabletop_passes_the_env_checker_and_seeds_deterministically():
    env = gymnasium.make("MuBlE/Tabletop-v0", overrides=SMALL)
    try:
        _check_env_quietly(env)
        first, _ = env.reset(seed=3)
        again, _ = env.reset(seed=3)
        assert all(np.array_equal(first[k], again[k]) for k in first)
        obs, reward, terminated, truncated, _ = env.step(np.array([0, 0, 1, 0, 0, 0, 1], dtype=np.float32))
        assert env.observation_space.contains(obs) and not terminated
        assert obs["ee_pos"][2] > first["ee_pos"][2]  # moved up
    finally:
        env.close()


@pytest.mark.slow
def test_tabletop_state_only_leaves_the_image_out_and_makes_no_renderer():
    env = gymnasium.make("MuBlE/Tabletop-v0", render=False)
    try:
        _check_env_quietly(env)
        assert "image" not in env.observation_space.spaces and env.unwrapped.components["renderer"] is None
        first, _ = env.reset(seed=3)
        obs, _, terminated, _, _ = env.step(np.array([0, 0, 1, 0, 0, 0, 1], dtype=np.float32))
        assert "image" not in obs and env.observation_space.contains(obs) and not terminated
        assert obs["ee_pos"][2] > first["ee_pos"][2]
    finally:
        env.close()


def test_tabletop_fast_rendering_defaults_apply_to_the_mujoco_renderer_only():
    from muble.gym.tabletop import FAST_MUJOCO_OVERRIDES, default_overrides

    assert set(FAST_MUJOCO_OVERRIDES) <= set(default_overrides([]))
    assert set(FAST_MUJOCO_OVERRIDES) <= set(default_overrides(["renderer=mujoco", "robot=UR5e"]))
    assert not set(FAST_MUJOCO_OVERRIDES) & set(default_overrides(["renderer=blender"]))
    with pytest.raises(ConfigError, match="render_mode"):
        gymnasium.make("MuBlE/Tabletop-v0", render=False, render_mode="rgb_array")


@pytest.mark.slow
def test_shopvrb2_draws_its_templates_by_the_configured_weights_and_checks_them_as_generate_does():
    mix = ["dataset.templates=[measure_weight_single,move_single]"]
    env = gymnasium.make("MuBlE/ShopVRB2-v0", overrides=[*mix, "dataset.template_weights=[0,1]"], render=False)
    try:
        drawn = {env.reset(seed=s)[1]["instruction"]["template_id"] for s in range(3)}
        assert drawn == {"move_single"}  # a zero weight is never drawn first, and move_single suits any scene
    finally:
        env.close()
    with pytest.raises(ConfigError, match=r"dataset.template_weights has 3 entries for 2 templates"):
        bad = gymnasium.make("MuBlE/ShopVRB2-v0", overrides=[*mix, "dataset.template_weights=[1,1,1]"],
                             render=False)
        try:
            bad.reset(seed=0)
        finally:
            bad.close()


@pytest.mark.slow
@pytest.mark.gl
def test_shopvrb2_keeps_one_renderer_across_resets_and_draws_what_a_fresh_one_draws():
    kept = gymnasium.make("MuBlE/ShopVRB2-v0", overrides=SMALL).unwrapped
    fresh = gymnasium.make("MuBlE/ShopVRB2-v0", overrides=SMALL).unwrapped
    try:
        kept.reset(seed=11)
        renderer = kept.factory._kept_renderer
        after_another, _ = kept.reset(seed=12)
        assert kept.factory._kept_renderer is renderer is not None  # the same renderer, its context kept
        first, _ = fresh.reset(seed=12)
        assert np.array_equal(after_another["images"]["front"], first["images"]["front"])
    finally:
        kept.close()
        fresh.close()
    assert kept.factory._kept_renderer is None  # closed with the environment, on its worker thread


@pytest.mark.slow
def test_with_a_split_both_environments_index_scenes_as_muble_generate_does():
    """``split=mini`` among the overrides: ``scene_index`` 2 is index 2 of the protocol's mini split as ``muble
    generate`` writes it (the shipped files; test_app_protocol), its objects and, in ShopVRB2, its instruction and
    template, generated at generate's image size while the environments render at their own small one."""
    from muble.dataset.protocol import load_protocol, shipped_files
    from muble.io.scene_io import scene_to_dict

    files = shipped_files(load_protocol("shopvrb2_v2"), "mini")
    shipped = json.loads(files["mini/instructions/SHOP_VRB2_mini_000002.json"])
    objects = [{k: v for k, v in o.items() if k != "mask"}
               for o in json.loads(files["mini/scenes/SHOP_VRB2_mini_000002.json"])["objects"]]
    split = ["protocol=shopvrb2_v2", "split=mini"]

    def unmasked(scene) -> list[dict]:
        return [{k: v for k, v in o.items() if k != "mask"} for o in scene_to_dict(scene)["objects"]]

    env = gymnasium.make("MuBlE/ShopVRB2-v0", overrides=split, render=False)
    try:
        _, info = env.reset(options={"scene_index": 2})
        assert info["instruction"]["instruction"] == shipped["instruction"]
        assert info["template"] == shipped["template_id"] and info["source"]["split"] == "mini"
        assert unmasked(env.unwrapped.spec_now.scene) == objects
        with pytest.raises(ConfigError, match="with split=mini an index's template is the one the split's"):
            env.reset(options={"scene_index": 2, "template": "move_single"})
    finally:
        env.close()
    table = gymnasium.make("MuBlE/Tabletop-v0", overrides=split, render=False)
    try:
        assert table.reset(options={"scene_index": 2})[1]["objects"] == len(objects)
        assert unmasked(table.unwrapped._scene(2)) == objects
    finally:
        table.close()
    with pytest.raises(ConfigError, match="unknown split 'minis' of protocol"):
        gymnasium.make("MuBlE/ShopVRB2-v0", overrides=["protocol=shopvrb2_v2", "split=minis"], render=False)
