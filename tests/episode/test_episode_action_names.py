"""Primitive names in sequence files: this project's registered names or the original release's, both ways."""
from __future__ import annotations

import numpy as np
import pytest

from muble import ActionCall, ConfigError, get_registry
from muble.episode.sequence import sequence_dict
from muble.io.action_names import ORIGINAL_NAMES, call_from_original, from_original, named, to_original
from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.episodes import run_symbolic_episode
from muble_plugins.common.synthetic import sample_scene

ORIGINAL = ("move", "approach_grasp", "grasp", "pick_up", "put_down", "release")


def test_names_map_both_ways():
    for name in get_registry().names("primitive"):
        assert from_original(to_original(name)) == name
    assert {to_original(n) for n in ("move", "approach", "close_gripper", "lift", "lower", "open_gripper")} \
        == set(ORIGINAL)
    assert all(to_original(from_original(n)) == n for n in ORIGINAL)
    assert set(ORIGINAL_NAMES) <= set(get_registry().names("primitive"))
    assert call_from_original(ActionCall("approach_grasp", {"target": 2})) == ActionCall("approach", {"target": 2})
    with pytest.raises(ConfigError, match="valid action name style names: original, registry"):
        named("move", "paper")


def _episode():
    task = get_registry().create("task", "measure_weight_multi", {})
    for i in range(50):
        scene = sample_scene(np.random.default_rng([3, i]), i)
        instructions = task.generate(scene, np.random.default_rng(i))
        if instructions:
            episode = run_symbolic_episode(instructions[0], scene, OracleAgent(task=task))
            return instructions[0], episode
    raise AssertionError("no scene for the template")


def test_sequence_files_write_original_names_on_request():
    instruction, episode = _episode()
    names = [o["robot"]["action"][0] for o in sequence_dict(instruction, episode, [])["observations"][1:]]
    original = sequence_dict(instruction, episode, [], action_names="original")
    renamed = [o["robot"]["action"][0] for o in original["observations"][1:]]
    assert names == [a.name for a in episode.actions]
    assert renamed == [to_original(n) for n in names] and "pick_up" in renamed and "lift" not in renamed
    assert [from_original(n) for n in renamed] == names
    assert [o["robot"]["action"][0] for o in original["observations_gt"][1:]] == renamed
