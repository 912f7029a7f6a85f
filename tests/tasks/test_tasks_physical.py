"""The physical task family (symbolic world): friction, centre of mass and loose contents, asked for, compared and
ordered. Generated where the scene carries the properties, hidden until pushed, balanced or shaken, the oracle
solves every instruction by measuring exactly the objects the program compares, and answers are judged within the
primitives' accuracy."""
from __future__ import annotations

import collections

import numpy as np
import pytest

from muble import Answer, Outcome, get_registry
from muble.core import physical_properties
from muble.core.observation import MEASURED_EXTRA, agent_view, leaks
from muble.programs.program import QUANTITIES, QUERY_STEPS, execute
from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.episodes import run_symbolic_episode
from muble_plugins.common.success import check
from muble_plugins.common.symbolic import SymbolicWorld
from muble_plugins.common.synthetic import sample_scenes
from muble_plugins.tasks.template_data import read_template_file
from muble_plugins.tasks.templates import PHYSICAL_FILE, PHYSICAL_TEMPLATES, TEMPLATES

SCENES = 150
MEASURING = {q.verb: name for name, q in QUANTITIES.items()}  # primitive -> the property it measures
NEW = ("friction", "com_offset", "rattles")
# Program step -> the new property it needs measured.
NEEDS = {f"{kind}_{p}": p for p in NEW for kind in ("filter", "order", "query")}


@pytest.fixture(scope="module")
def generated():
    """(template, task, instruction, scene) of every physical template on 150 seeded synthetic scenes."""
    tasks = {name: get_registry().create("task", name, {}) for name in PHYSICAL_TEMPLATES}
    out = []
    for scene in sample_scenes(23, SCENES, properties=True):
        for name, task in tasks.items():
            for ins in task.generate(scene, np.random.default_rng([23, scene.image_index])):
                out.append((name, task, ins, scene))
    return out


def test_physical_templates_are_tasks_outside_the_default_mix():
    from muble.io.instructions_io import SHOPVRB2_TEMPLATES

    assert len(PHYSICAL_TEMPLATES) == 7
    assert set(PHYSICAL_TEMPLATES) <= set(get_registry().names("task"))
    assert not set(PHYSICAL_TEMPLATES) & (set(SHOPVRB2_TEMPLATES) | set(TEMPLATES))
    # One query per property, four manipulation templates whose targets depend on a measured property.
    finals = collections.Counter(spec.program[-1]["type"] for spec in read_template_file(PHYSICAL_FILE))
    assert {"query_friction", "query_com_offset", "query_rattles"} <= set(finals)
    assert {QUERY_STEPS[k] for k in finals if k in QUERY_STEPS} == {"friction", "com_offset", "rattles"}
    assert sum(finals[k] for k in ("move_to", "pick_up", "stack")) >= 4


def test_scenes_without_the_properties_get_no_physical_instruction():
    tasks = [get_registry().create("task", name, {}) for name in PHYSICAL_TEMPLATES]
    for scene in sample_scenes(23, 20):
        assert not [i for t in tasks for i in t.generate(scene, np.random.default_rng(0))]


def test_every_physical_template_yields_instructions(generated):
    counts = collections.Counter(name for name, *_ in generated)
    assert set(counts) == set(PHYSICAL_TEMPLATES), counts
    assert counts["measure_friction_single"] >= 0.9 * SCENES and counts["measure_com_single"] >= 0.9 * SCENES
    assert counts["measure_contents_single"] >= 0.4 * SCENES
    for _name, _, ins, scene in generated:
        assert 5 <= len(ins.instruction.split()) <= 16, ins.instruction
        truth = execute(ins.program, scene, weights="ground_truth")
        assert truth.outputs[-1] == ins.program[-1]["output"]


def _measured_objects(actions) -> dict[str, list[int]]:
    """Property -> the objects measured for it, in order (the object a measuring primitive acted on: the last one
    grasped before it)."""
    out: dict[str, list[int]] = collections.defaultdict(list)
    for k, action in enumerate(actions):
        if action.name in MEASURING:
            held = next(a.params["target"] for a in reversed(actions[:k]) if a.name == "close_gripper")
            out[MEASURING[action.name]].append(held)
    return out


def test_oracle_solves_every_physical_instruction_measuring_only_what_it_compares(generated):
    for _name, task, ins, scene in generated:
        result = run_symbolic_episode(ins, scene, OracleAgent(task=task))
        assert result.outcome is Outcome.SUCCESS, (ins.instruction, [str(a) for a in result.actions])
        measured = _measured_objects(result.actions)
        step = next(s for s in ins.program if s["type"] in NEEDS)
        prop = NEEDS[step["type"]]
        compared = ins.program[ins.program.index(step) - 1]["output"]
        assert sorted(measured[prop]) == sorted(compared), (ins.instruction, dict(measured), compared)
        assert set(measured) == {prop}, "nothing else is measured"


def test_properties_stay_hidden_until_measured_and_then_show_what_was_measured(generated):
    name, task, ins, scene = next(g for g in generated if g[0] == "move_friction")
    world = SymbolicWorld(scene)
    view = world.observe(None, 0).scene
    assert leaks(view, world.measured) == []
    for o in view.objects:
        assert not set(physical_properties.SCENE_KEYS.values()) & set(o.extra)
        assert not set(MEASURED_EXTRA.values()) & set(o.extra)
    at = next(k for k, s in enumerate(ins.program) if s["type"] in NEEDS)
    compared = ins.program[at - 1]["output"]
    trace = execute(ins.program, view)
    assert trace.pending_property == "friction" and trace.pending == tuple(compared) and not trace.complete
    # Measured values known to the program: it runs on, and the view shows what was measured, nothing else.
    values = {i: physical_properties.friction_of(scene.object(i)) for i in compared}
    assert execute(ins.program, view, known={"friction": values}).complete
    first = compared[0]

    shown = agent_view(scene, {first: {"weight": 100.0, "friction": values[first]}})
    assert shown.object(first).extra[MEASURED_EXTRA["friction"]] == values[first]
    assert leaks(shown, {first: {"weight": 100.0, "friction": values[first]}}) == []
    assert leaks(shown, {}) != []


@pytest.mark.parametrize("template, right, wrong", [
    ("measure_friction_single", lambda t: [t[0] * 1.08], lambda t: [t[0] * 1.15]),
    ("measure_com_single", lambda t: [t[0] + 4.5], lambda t: [t[0] + 6.0]),
    ("measure_contents_single", lambda t: ["yes" if t[0] else "no"], lambda t: [not t[0]]),
])
def test_answers_are_judged_within_the_primitives_accuracy(generated, template, right, wrong):
    name, task, ins, scene = next(g for g in generated if g[0] == template)
    truth = ins.program[-1]["output"]
    assert check(ins, scene, Answer(right(truth))) is Outcome.SUCCESS
    assert check(ins, scene, Answer(wrong(truth))) is Outcome.INCORRECT_ANSWER
    assert check(ins, scene, Answer({ins.program[-2]["output"][0]: right(truth)[0]})) is Outcome.SUCCESS
    assert check(ins, scene, Answer(["maybe"])) is Outcome.INCORRECT_ANSWER


def test_measurements_known_to_the_program_count_as_the_primitives_report_them(generated):
    """A centre of mass is reported as [x, y] mm (``balance``) and compared by its distance from the centre."""
    name, task, ins, scene = next(g for g in generated if g[0] == "pick_up_com")
    at = next(k for k, s in enumerate(ins.program) if s["type"] in NEEDS)
    compared = ins.program[at - 1]["output"]
    view = SymbolicWorld(scene).observe(None, 0).scene
    readings = {i: physical_properties.com_offset_mm(scene.object(i)) for i in compared}
    trace = execute(ins.program, view, known={"com_offset": readings})
    assert trace.complete and trace.final == ins.program[-1]["output"]
    swapped = {i: [0.0, 0.0] if i == trace.final[0] else [30.0, 40.0] for i in compared}  # 50 mm off: the others
    picked = execute(ins.program, view, known={"com_offset": swapped}).final
    assert picked != trace.final if ins.program[at]["input_value"] == "furthest off-centre" else picked == trace.final
