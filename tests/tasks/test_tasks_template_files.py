"""Templates as data: the built-in templates from their file generate exactly what the Python ones did, and a
template added as a file only generates instructions, ground truth and is solved by the oracle."""
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


# What every template (the built-in files' and RELATED_WEIGHTS) offered on scenes 0-24 of sample_scenes(5, 25), as
# recorded when conditions were compiled into Python source: per template, how many options, a digest of them all
# and of the dear constraints' verdict on the first 40, and of one instruction per template drawn on each scene.
OPTIONS_RECORDED = {
    "measure_stiffness_single": (77, "5f16652c1929fadf65da91bf6bf700b85c4c53084c43a3dccf1666c1a1c1af50"),
    "measure_weight_beside": (159, "49670f958fa4eb8ff631375b1ebb84a1c33cdb83ea80857bcd5aab3d80e0f16a"),
    "measure_weight_multi": (63, "2a9efc9e9b2a3a4048586c8dee46d6b3494db486afd475dfa9ae8c589aaf7be6"),
    "measure_weight_single": (84, "6a9c894db237ace6db13c0c00a17fc79d54026d2894326bad64295390d669fc6"),
    "move_single": (168, "a6e10be4b92e271e17518f29cd6bc181e7e00bda2b417f72bc752f4021dd7938"),
    "move_weight": (248, "be5a50e9ffa857c71c8016f9ee79af15c4d9188b3ab0cd3849aede5b8909fd10"),
    "pick_up_lightest": (124, "d858fc15abf5c3d15192e194512c2420b130d28f7966191cb2a4163aa97ca621"),
    "pick_up_stiffness": (70, "f4330e0c6cc0a9f25442cba059f43381910b79c3b12cc915a5cd9ba31f15a1a9"),
    "remove": (266, "99a049efedd035288f224783907b4c52c7f0302a65ec32193e8a29843dfeec3b"),
    "stack_order": (13, "81cfa61f58f09e5adefe85733532df0bb5f503f032d5936ca9b608c185088e4b"),
    "stack_simple": (110, "3b537de3a13b32d799060d584e5eec25ff162dd9fc6689f081c0f7c92270a96c"),
    "stack_stiffness_order": (4, "70d7824c385f6d93185a6b8782cc3b1c63604548dc3bc05915aca5f106e0873a"),
    "stack_three": (60, "036379b6332acbf7cc3582e64538ea97e364725f79d318eac366d82c5dfb83dd"),
    "stack_weight": (124, "02b7fafb13866c9746b775dbf94c667d4144a5dda347db6d54ece5da4848080a"),
}
INSTRUCTIONS_RECORDED = "dd5b71834c127993fe68f28ce2fb350808f210f75f60f5e5e8ac94a0ada92be7"


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
