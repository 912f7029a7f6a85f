"""The task mix of a split: templates and object counts in their shares per index, scenes generated to suit them."""
from __future__ import annotations

import collections
import json

import numpy as np
import pytest

from muble import ConfigError, get_registry
from muble.core.errors import SceneGenerationError
from muble.generation import SceneGenerator
from muble.generation.task_mix import COUNT_KEY, TEMPLATE_KEY, balanced_choice, suited_scene, template_weights
from muble.io.instructions_io import SHOPVRB2_TEMPLATES
from muble.io.scene_io import scene_to_dict
from tests.generation.builtin import BUILTIN

TEMPLATES = list(SHOPVRB2_TEMPLATES)


def test_the_tasks_plugins_data_defines_the_shopvrb2_templates_in_their_overall_order():
    from muble_plugins.tasks.templates import TEMPLATES as DEFINED

    assert [t.template_id for t in sorted(DEFINED.values(), key=lambda t: t.index)] == TEMPLATES
    assert [DEFINED[name].index for name in TEMPLATES] == list(range(10))
    assert set(TEMPLATES) <= set(get_registry().names("task"))


def test_equal_weights_give_every_template_once_in_every_block_of_ten():
    drawn = [balanced_choice([1.0] * 10, 3, i, TEMPLATE_KEY) for i in range(1000)]
    assert collections.Counter(drawn) == {k: 100 for k in range(10)}
    assert all(sorted(drawn[b:b + 10]) == list(range(10)) for b in range(0, 1000, 10))
    assert drawn == [balanced_choice([1.0] * 10, 3, i, TEMPLATE_KEY) for i in range(1000)]  # a pure function of the index
    assert drawn[:30] != [balanced_choice([1.0] * 10, 4, i, TEMPLATE_KEY) for i in range(30)]  # shuffled per seed


def test_weights_and_object_counts_are_apportioned_at_every_block():
    drawn = [balanced_choice([2.0, 1.0, 0.0, 1.0], 0, i, TEMPLATE_KEY) for i in range(400)]
    assert collections.Counter(drawn) == {0: 200, 1: 100, 3: 100}
    counts = [balanced_choice([0.473, 0.527], 0, i, COUNT_KEY) for i in range(1000)]
    assert counts.count(0) == 473
    for n in range(2, 1000, 2):  # any whole number of blocks holds each count within one of its share
        assert abs(counts[:n].count(0) - 0.473 * n) <= 1.0


def test_bad_weights_are_refused_with_what_to_change():
    with pytest.raises(ConfigError, match="one weight per template"):
        template_weights(["a", "b"], [1.0])
    with pytest.raises(ConfigError, match="not all zero"):
        template_weights(["a", "b"], [0.0, 0.0])
    assert template_weights(["a", "b"], []) == [1.0, 1.0]


@pytest.fixture(scope="module")
def generator():
    objects = get_registry().create("object_set", "shopvrb2")
    g = SceneGenerator({**BUILTIN, "stability": False, "reach_check": False, "masks": False}, seed=11, object_set=objects)
    yield g
    g.close()


def _suited(generator, index, tasks):
    return suited_scene(generator, tasks, [1.0] * len(tasks), 11, index, lambda i: np.random.default_rng([11, i, 1]))


@pytest.mark.gl
def test_scenes_suit_the_template_drawn_for_their_index(generator):
    registry = get_registry()
    tasks = {t: registry.create("task", t, {}) for t in TEMPLATES}
    seen = []
    for index in range(10):
        suited = _suited(generator, index, tasks)
        assert suited.instruction.template_id == suited.template
        assert len(suited.scene.objects) == 4 + balanced_choice([0.473, 0.527], 11, index, COUNT_KEY)
        assert suited.ground_truth and suited.ground_truth == tasks[suited.template].ground_truth(
            suited.instruction, suited.scene)
        seen.append(suited.template)
    assert sorted(seen) == sorted(TEMPLATES)
    again = _suited(generator, 9, tasks)
    assert json.dumps(scene_to_dict(again.scene)) == json.dumps(scene_to_dict(suited.scene))
    assert again.instruction.instruction == suited.instruction.instruction


class _NeverApplies:
    def generate(self, scene, rng):
        return []


@pytest.mark.gl
def test_a_template_no_scene_suits_fails_naming_it(generator):
    with pytest.raises(SceneGenerationError, match="suits template 'never'.*template_weights") as info:
        suited_scene(generator, {"never": _NeverApplies()}, [1.0], 11, 0, lambda i: np.random.default_rng(i),
                     max_samples=2)
    assert info.value.reasons["not accepted"] == 2 * generator.config.layout_tries - info.value.reasons.get(
        "placement", 0)


@pytest.mark.gl
def test_distractors_are_objects_beyond_the_count_that_no_step_of_the_instruction_picks():
    from muble.generation.task_mix import unreferenced

    objects = get_registry().create("object_set", "shopvrb2")
    plain = {**BUILTIN, "stability": False, "reach_check": False, "masks": False}
    g = SceneGenerator({**plain, "distractors": 2}, seed=11, object_set=objects)
    registry = get_registry()
    tasks = {t: registry.create("task", t, {}) for t in TEMPLATES}
    try:
        for index in range(10):
            suited = _suited(g, index, tasks)
            scene, program = suited.scene, suited.instruction.program
            assert len(scene.objects) == 4 + balanced_choice([0.473, 0.527], 11, index, COUNT_KEY) + 2
            listed = scene.extra["generator"]["distractors"]
            assert len(listed) >= 2 and listed == unreferenced(program, scene)
            picked = set(_ints([step.get("output") for step in program if step["type"] != "scene"]))
            assert picked and not picked & set(listed), (suited.template, listed, program)
            assert scene_to_dict(scene)["generator"]["distractors"] == listed  # in the scene file, top level
    finally:
        g.close()
    # Without distractors the scene file says nothing of them.
    suited = _suited(SceneGenerator(plain, seed=11, object_set=objects), 0, tasks)
    assert "distractors" not in suited.scene.extra["generator"]


def _ints(value):
    if isinstance(value, list):
        for v in value:
            yield from _ints(v)
    elif isinstance(value, int):
        yield value
