"""Templates as data: the built-in templates from their file generate the pinned instructions and ground truth, and
a template added as a file only generates instructions, ground truth and is solved by the oracle."""
from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from muble import ConfigError, Outcome, get_registry
from muble.io.instructions_io import instruction_to_dict
from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.episodes import run_symbolic_episode
from muble_plugins.common.synthetic import sample_scenes
from muble_plugins.tasks.generator import generate_instructions
from muble_plugins.tasks.template_data import expand_optional_words, read_template_file
from muble_plugins.tasks.tasks import template_file_tasks
from tests.support.plugins import clear_caches

# What the built-in template file generates on scenes 0-199 of sample_scenes(14, 200) (instruction i of scene s
# drawn with default_rng([14, s])): the instructions, programs and outputs of one instruction per template, of
# every option, and the oracle's ground-truth primitives on the first 40 scenes. A change to a template, its
# options, the room check or the synthetic scenes shows here.
ONE_PER_TEMPLATE = (1430, "6f9a62e7628acb768956b9e9218c15f51d29bc86c0127fe220756fb07c10cd58")
EVERY_OPTION = (6915, "b387e97cc7726236bac62110a538beb5aa905a4f900b2584088c06e25e93d584")
GROUND_TRUTH_40 = "53c8c777f9a301dc12dc2558f8b4c3025a7181ec40e73704bdaef9757be13c4e"


def _digest(per_template: int) -> tuple[int, str]:
    h, n = hashlib.sha256(), 0
    for scene in sample_scenes(14, 200):
        for ins in generate_instructions(scene, np.random.default_rng([14, scene.image_index]),
                                         per_template=per_template):
            h.update(json.dumps(instruction_to_dict(ins), sort_keys=True).encode())
            n += 1
    return n, h.hexdigest()


def test_builtin_template_file_generates_the_pinned_instructions():
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


# What every template (the built-in files' and RELATED_WEIGHTS) offers on scenes 0-24 of sample_scenes(5, 25):
# per template, how many options, a digest of them all and of the dear constraints' verdict on the first 40, and of
# one instruction per template drawn on each scene.
OPTIONS_RECORDED = {
    "measure_stiffness_single": (69, "9e7a0f2a5cf842217385e2e7be5141c81c2cbc0bbec1cc26714235d0da2f2421"),
    "measure_weight_beside": (125, "127e0d92fe0365eeb9794240bd615130aaa783fb93aec98a0b77da69279e9c2a"),
    "measure_weight_multi": (49, "913debff9f7f07f8721e9159b813ce20fdf47be2fafcdb43bd315144058c4480"),
    "measure_weight_single": (75, "29db85c53ea04c7c5114b716a1676778553b43072d3cff4217035f3217ffcb03"),
    "move_single": (150, "b8a010f68826cc406d8b142cc22d87a839fd16ea2b15bad6863cdd24000cc5aa"),
    "move_weight": (194, "170c80a947a0d70d09ba725c23feb9058e7c84179949c94b9a981337ed561382"),
    "pick_up_lightest": (97, "95f40d20a91770a44de190b7f7404a12fe76a180d9d8475843d39fb466ecc9b1"),
    "pick_up_stiffness": (58, "ed7cf39910742189aeb7e3c82f60df38115d59ceab6d00ea8860ec90c9e1fdb9"),
    "remove": (225, "e7ea6c9884e5019a85a34b3c9a3044e6417191e1d5f980257dcdcffbf1e6b606"),
    "stack_order": (7, "9257dd1f4e8fc8668fd66067e41c89fa15f1d35e979e45ac26bdfbd9f8e82d2a"),
    "stack_simple": (95, "79fe20b032c0b690c9fb656e45ee4c9d849bafe0f310f9854dd6fe2b7c97984a"),
    "stack_stiffness_order": (1, "26a8558ef4a9e673f7c0c4672c57a592d108fa9980860f9015521415932b4b0f"),
    "stack_three": (29, "e715c62708f3e28b4149bbf6ee0eca47c87bb6d4b06edb092d65b2ec765c0f7b"),
    "stack_weight": (80, "2d8c2c37e435057e376f51c675f766c4fb69d75ce9b9776b5f20ed9d23285a55"),
}
INSTRUCTIONS_RECORDED = "a651ee8c10dfa7ff22894887bd0ecf48373ac496ff1bebce5e7d4ce7ce76b09b"


def _template_records(tmp_path) -> tuple[dict[str, tuple[int, str]], str]:
    from muble.programs.descriptions import SceneIndex
    from muble_plugins.tasks.generator import generate_for_template
    from muble_plugins.tasks.template_data import DataTemplate
    from muble_plugins.tasks.templates import BUILTIN_FILE, STIFFNESS_FILE, OptionContext, load_templates

    path = tmp_path / "beside.yaml"
    path.write_text(RELATED_WEIGHTS)
    specs = read_template_file(BUILTIN_FILE) + read_template_file(STIFFNESS_FILE) + read_template_file(path)
    templates = {**load_templates(BUILTIN_FILE), **load_templates(STIFFNESS_FILE), **load_templates(path)}
    data = {spec.template_id: DataTemplate(spec) for spec in specs}
    digests = {t: [0, hashlib.sha256()] for t in data}
    words = hashlib.sha256()
    for scene in sample_scenes(5, 25):
        index = SceneIndex(scene)
        for name, template in data.items():
            context = OptionContext(index, 2.0)
            options = list(template.options(context))
            digests[name][0] += len(options)
            digests[name][1].update(repr(options).encode())
            digests[name][1].update(repr([template.feasible(o, context) for o in options[:40]]).encode())
            for ins in generate_for_template(templates[name], scene, np.random.default_rng([5, scene.image_index]),
                                             index=index):
                words.update(json.dumps(instruction_to_dict(ins), sort_keys=True).encode())
    return {t: (n, h.hexdigest()) for t, (n, h) in digests.items()}, words.hexdigest()


def test_every_template_offers_the_options_and_instructions_recorded(tmp_path):
    options, instructions = _template_records(tmp_path)
    assert options == OPTIONS_RECORDED
    assert instructions == INSTRUCTIONS_RECORDED


def test_conditions_are_interpreted_not_generated_as_source():
    import ast
    import inspect

    import muble_plugins.tasks.template_data as template_data

    calls = {n.func.id for n in ast.walk(ast.parse(inspect.getsource(template_data)))
             if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
    assert not calls & {"exec", "eval", "compile"}


@pytest.mark.parametrize("constraint,says", [
    ("{type: is, target: O1, property: __class__}", "unknown property '__class__'"),
    ("{type: max_count, target: [O1, REL], value: 3}", "max_count needs a target of 1 reference"),
])
def test_a_bad_constraint_is_a_config_error(tmp_path, constraint, says):
    from muble_plugins.tasks.template_data import DataTemplate

    path = tmp_path / "bad.yaml"
    path.write_text(RELATED_WEIGHTS.replace("{type: min_count, target: {related: [O1, REL]}, value: 1}", constraint))
    (spec,) = read_template_file(path)
    with pytest.raises(ConfigError, match=says):
        DataTemplate(spec)
