"""Templates as data: the built-in templates from their file generate exactly what the Python ones did, and a
template added as a file only generates instructions, ground truth and is solved by the oracle."""
from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from muble import ConfigError, Outcome, get_registry
from muble.core.instructions_io import instruction_to_dict
from muble_plugins.tasks.agents import OracleAgent
from muble_plugins.tasks.episodes import run_symbolic_episode
from muble_plugins.tasks.generator import generate_instructions
from muble_plugins.tasks.synthetic import sample_scenes
from muble_plugins.tasks.template_data import expand_optional_words, read_template_file
from muble_plugins.tasks.tasks import template_file_tasks
from muble.testing import clear_caches

# What the ten templates written in Python generated on scenes 0-199 of sample_scenes(14, 200) (instruction i of
# scene s drawn with default_rng([14, s])): the instructions, programs and outputs of one instruction per
# template, of every option, and the oracle's ground-truth primitives on the first 40 scenes.
ONE_PER_TEMPLATE = (1459, "023e11e56c50a04fdec954a880fa60f5b54b0ff457f520cd42400f4032881def")
EVERY_OPTION = (7991, "2fda2bdf8e6f95f891250379184bcb355abbb3985b85f442d389e96da1922ca1")
GROUND_TRUTH_40 = "b9803cb8008d120d0d2e4f48329ae687ee80e72c2a241e2b51933c216df79c5e"


def _digest(per_template: int) -> tuple[int, str]:
    h, n = hashlib.sha256(), 0
    for scene in sample_scenes(14, 200):
        for ins in generate_instructions(scene, np.random.default_rng([14, scene.image_index]),
                                         per_template=per_template):
            h.update(json.dumps(instruction_to_dict(ins), sort_keys=True).encode())
            n += 1
    return n, h.hexdigest()


def test_builtin_template_file_generates_what_the_python_templates_did():
    assert _digest(1) == ONE_PER_TEMPLATE


@pytest.mark.slow
def test_builtin_template_file_matches_on_every_option_and_ground_truth():
    assert _digest(-1) == EVERY_OPTION
    h, tasks = hashlib.sha256(), {}
    for scene in sample_scenes(14, 40):
        for ins in generate_instructions(scene, np.random.default_rng([14, scene.image_index])):
            task = tasks.setdefault(ins.template_id, get_registry().create("task", ins.template_id, {}))
            h.update(str(task.ground_truth(ins, scene)).encode())
    assert h.hexdigest() == GROUND_TRUTH_40


RELATED_WEIGHTS = """
templates:
  - template_id: measure_weight_beside
    task_id: measure_weight
    index: 20
    description: measure the weight of the objects on one side of an object
    text:
      - "What do the objects <REL> of the <O1> weigh?"
      - "Measure the weight of [all] objects <REL> of the <O1>."
    parameters:
      - {name: O1, type: object}
      - {name: REL, type: relation}
    constraints:
      - {type: min_count, target: {related: [O1, REL]}, value: 1}
      - {type: max_count, target: {related: [O1, REL]}, value: 3}
      - {type: is, target: {related: [O1, REL]}, property: pickupable}
    program:
      - {type: scene}
      - {describe: O1}
      - {type: filter_relate, input_value: <REL>}
      - {type: query_weight}
"""


def test_a_template_added_as_a_file_only_is_generated_planned_and_solved(tmp_path):
    path = tmp_path / "beside.yaml"
    path.write_text(RELATED_WEIGHTS)
    task = template_file_tasks(path)["measure_weight_beside"]()
    made = solved = 0
    for scene in sample_scenes(3, 30):
        for ins in task.generate(scene, np.random.default_rng(scene.image_index)):
            made += 1
            assert ins.program[-2]["type"] == "filter_relate" and ins.template_id == "measure_weight_beside"
            assert task.ground_truth(ins, scene)[-1].name == "weigh"
            episode = run_symbolic_episode(ins, scene, OracleAgent(task=task))
            solved += episode.outcome is Outcome.SUCCESS
    assert made >= 10 and solved == made


def test_template_files_register_as_tasks_from_the_environment(tmp_path, monkeypatch):
    path = tmp_path / "beside.yaml"
    path.write_text(RELATED_WEIGHTS)
    monkeypatch.setenv("MUBLE_TEMPLATE_FILES", str(path))
    clear_caches()
    try:
        task = get_registry().create("task", "measure_weight_beside", {})
        assert task.template.texts[1] == "Measure the weight of all objects <REL> of the <O1>."
    finally:
        monkeypatch.delenv("MUBLE_TEMPLATE_FILES")
        clear_caches()


def test_optional_words_expand():
    assert expand_optional_words("Stack [all] <O1s> from [the] heaviest.") == [
        "Stack all <O1s> from the heaviest.", "Stack all <O1s> from heaviest.", "Stack <O1s> from the heaviest.",
        "Stack <O1s> from heaviest."]


@pytest.mark.parametrize("change,says", [
    ("type: query_weight}", "field 'program'"),
    ("{name: REL, type: relation}", "field 'parameters'"),
    ("type: min_count,", "unknown constraint type 'at_least'"),
    ('"What do the objects <REL> of the <O1> weigh?"', "unknown parameter 'O9'"),
])
def test_a_bad_template_file_names_template_and_field(tmp_path, change, says):
    bad = {"type: query_weight}": "typo: query_weight}", "{name: REL, type: relation}": "{name: REL, type: colour}",
           "type: min_count,": "type: at_least,",
           '"What do the objects <REL> of the <O1> weigh?"': '"What does the <O9> weigh?"'}[change]
    path = tmp_path / "bad.yaml"
    path.write_text(RELATED_WEIGHTS.replace(change, bad))
    with pytest.raises(ConfigError, match=f"template 'measure_weight_beside'.*{says}"):
        read_template_file(path)


def test_compiled_options_agree_with_the_interpreted_constraints(tmp_path):
    from muble.core.descriptions import SceneIndex
    from muble_plugins.tasks.template_data import DataTemplate
    from muble_plugins.tasks.templates import OptionContext

    path = tmp_path / "beside.yaml"
    path.write_text(RELATED_WEIGHTS)
    builtin = __import__("muble_plugins.tasks.templates", fromlist=["BUILTIN_FILE"])
    specs = read_template_file(path) + read_template_file(builtin.BUILTIN_FILE) + \
        read_template_file(builtin.STIFFNESS_FILE)
    for scene in sample_scenes(5, 25):
        index = SceneIndex(scene)
        for spec in specs:
            data = DataTemplate(spec)
            assert list(data.options(OptionContext(index, 2.0))) == \
                list(data.options_interpreted(OptionContext(index, 2.0)))
