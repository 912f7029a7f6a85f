"""The stiffness task family (symbolic world): generated where the scene allows, stiffness hidden until squeezed,
squeeze's preconditions as the physical primitive's, the oracle solves every instruction, answers judged per
object within 5 %, and none of it in the default SHOP-VRB2 mix."""
from __future__ import annotations

import collections
import re

import numpy as np
import pytest

from muble import ActionCall, Answer, Outcome, PlanningError, get_registry
from muble.core.observation import MEASURED_STIFFNESS, leaks
from muble.programs.program import STIFFNESS_STEPS, execute
from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.episodes import run_symbolic_episode
from muble_plugins.common.symbolic import SymbolicWorld
from muble_plugins.common.synthetic import sample_scenes
from muble_plugins.tasks.generator import generate_instructions
from muble_plugins.tasks.templates import STIFFNESS_TEMPLATES, TEMPLATES

STIFFNESS = ("measure_stiffness_single", "pick_up_stiffness", "stack_stiffness_order")
SCENES = 200


@pytest.fixture(scope="module")
def generated():
    """(template, task, instruction, scene) of every stiffness template on 200 seeded synthetic scenes."""
    tasks = {name: get_registry().create("task", name, {}) for name in STIFFNESS}
    out = []
    for scene in sample_scenes(14, SCENES):
        for name, task in tasks.items():
            for ins in task.generate(scene, np.random.default_rng([14, scene.image_index])):
                out.append((name, task, ins, scene))
    return out


def test_stiffness_templates_are_tasks_outside_the_default_mix():
    from muble.app.config import SHOPVRB2_TEMPLATES

    assert set(STIFFNESS_TEMPLATES) == set(STIFFNESS)
    assert set(STIFFNESS) <= set(get_registry().names("task"))
    assert not set(STIFFNESS) & set(SHOPVRB2_TEMPLATES) and not set(STIFFNESS) & set(TEMPLATES)
    scene = sample_scenes(14, 1)[0]
    assert all(i.template_id in TEMPLATES for i in generate_instructions(scene, np.random.default_rng(0)))
    chosen = generate_instructions(scene, np.random.default_rng(0), templates=["measure_stiffness_single"])
    assert [i.template_id for i in chosen] == ["measure_stiffness_single"]


def test_every_stiffness_template_yields_instructions_over_200_scenes(generated):
    counts = collections.Counter(name for name, *_ in generated)
    # Where the scene allows: a pickupable object; two or more of a kind apart in stiffness; bowls to stack (two or
    # more bowls, in about one scene in twenty).
    assert counts["measure_stiffness_single"] >= 0.9 * SCENES
    assert counts["pick_up_stiffness"] >= 0.45 * SCENES
    assert counts["stack_stiffness_order"] >= 6
    for _name, _, ins, scene in generated:
        assert 5 <= len(ins.instruction.split()) <= 16
        steps = [s["type"] for s in ins.program]
        assert {"query_stiffness", "filter_stiffness", "order_stiffness"} & set(steps)
        truth = execute(ins.program, scene, weights="ground_truth")
        assert truth.outputs[-1] == ins.program[-1]["output"]


def test_oracle_solves_every_stiffness_instruction_by_squeezing_first(generated):
    for _name, task, ins, scene in generated[::2]:
        result = run_symbolic_episode(ins, scene, OracleAgent(task=task))
        assert result.outcome is Outcome.SUCCESS, (ins.instruction, [str(a) for a in result.actions])
        first = next(k for k, s in enumerate(ins.program) if s["type"] in STIFFNESS_STEPS)
        compared = ins.program[first - 1]["output"]
        squeezed = []
        for k, action in enumerate(result.actions):
            if action.name == "squeeze":
                squeezed.append(next(a.params["target"] for a in reversed(result.actions[:k])
                                     if a.name == "close_gripper"))
        assert sorted(squeezed) == sorted(set(squeezed)), "each object squeezed once"
        assert set(compared) <= set(squeezed), (ins.instruction, compared, squeezed)
        # Every squeeze before any object is put on another or held up for good: measure, then act.
        last_squeeze = max(k for k, a in enumerate(result.actions) if a.name == "squeeze")
        assert not any(a.name == "lower" and a.params.get("target") is not None
                       for a in result.actions[:last_squeeze])


def test_ground_truth_plans_squeeze_right_after_grasping(generated):
    for _name, task, ins, scene in generated[::5]:
        plan = task.ground_truth(ins, scene)
        assert 4 <= len(plan) <= 46
        for k, action in enumerate(plan):
            if action.name == "squeeze":
                assert plan[k - 1].name == "close_gripper", [str(a) for a in plan]
        assert all(o.stiffness is not None and MEASURED_STIFFNESS not in o.extra for o in scene.objects)


def test_stiffness_is_hidden_until_squeezed_and_squeeze_needs_a_grasped_object():
    scene = next(s for s in sample_scenes(14, 20) if any(o.pickupable for o in s.objects))
    obj = next(o for o in scene.objects if o.pickupable)
    world = SymbolicWorld(scene)
    view = world.observe(None, 0).scene
    assert all(o.stiffness is None and MEASURED_STIFFNESS not in o.extra for o in view.objects)
    assert not world.apply(ActionCall("squeeze")).success  # empty gripper
    for call in (ActionCall("move", {"target": obj.id}), ActionCall("approach", {"target": obj.id})):
        assert world.apply(call).success
    assert not world.apply(ActionCall("squeeze")).success  # approached, not grasped
    assert world.apply(ActionCall("close_gripper", {"target": obj.id})).success
    squeezed = world.apply(ActionCall("squeeze"))  # grasped, standing on the table: as the physical primitive
    assert squeezed.success and squeezed.measurement == obj.stiffness
    view = world.observe(squeezed, 4).scene
    assert view.object(obj.id).extra[MEASURED_STIFFNESS] == obj.stiffness
    assert view.object(obj.id).stiffness is None
    assert all(MEASURED_STIFFNESS not in o.extra for o in view.objects if o.id != obj.id)
    assert leaks(view, world.measured) == []
    assert world.apply(ActionCall("lift")).success and world.apply(ActionCall("squeeze")).success  # lifted too


def test_measured_programs_stop_at_unmeasured_stiffness(generated):
    name, task, ins, scene = next(g for g in generated if g[0] == "pick_up_stiffness")
    trace = execute(ins.program, scene)
    ids = ins.program[-3]["output"]
    assert trace.pending_stiffness == tuple(ids) and not trace.complete
    with pytest.raises(PlanningError, match="squeeze objects"):
        _ = trace.final
    known = {i: scene.object(i).stiffness for i in ids}
    assert execute(ins.program, scene, known_stiffness=known).final == ins.program[-1]["output"]


def test_stiffness_answers_are_judged_per_object_within_five_percent(generated):
    name, task, ins, scene = next(g for g in generated if g[0] == "measure_stiffness_single")
    (truth,) = ins.program[-1]["output"]
    (target,) = ins.program[-2]["output"]
    assert task.check(ins, scene, Answer([truth * 1.04])) is Outcome.SUCCESS
    assert task.check(ins, scene, Answer(truth * 0.96)) is Outcome.SUCCESS
    assert task.check(ins, scene, Answer({str(target): truth})) is Outcome.SUCCESS
    assert task.check(ins, scene, Answer([truth * 1.06])) is Outcome.INCORRECT_ANSWER
    assert task.check(ins, scene, Answer({str(target + 1): truth})) is Outcome.INCORRECT_ANSWER
    assert task.check(ins, scene, Answer([float("nan")])) is Outcome.INCORRECT_ANSWER
    assert task.check(ins, scene, None) is Outcome.INCORRECT_ANSWER


def test_only_measurable_objects_take_part(tmp_path):
    from muble_plugins.tasks.tasks import template_file_tasks
    from muble_plugins.tasks.templates import STIFFNESS_FILE

    text = re.sub(r"property: (name|model), values: \[[^\]]*\]", "property: name, values: [mug]",
                  STIFFNESS_FILE.read_text())
    path = tmp_path / "mugs.yaml"
    path.write_text(text)
    task = template_file_tasks(path)["measure_stiffness_single"]()
    named = [scene.object(ins.program[-2]["output"][0]).name for scene in sample_scenes(14, 60)
             for ins in task.generate(scene, np.random.default_rng(0))]
    assert named and set(named) == {"mug"}


def test_episode_sources_draw_from_the_configured_mix():
    """Gymnasium and ``muble serve`` episodes come from ``dataset.templates`` unless templates are named."""
    from muble.app.config import SHOPVRB2_TEMPLATES, compose
    from muble.episode.sources import EpisodeFactory

    factory = EpisodeFactory(compose("run", []), render=False)
    assert factory.mix == list(SHOPVRB2_TEMPLATES) and set(STIFFNESS) <= set(factory.templates)
    chosen = EpisodeFactory(compose("run", ["dataset.templates=[pick_up_stiffness]"]), render=False)
    assert chosen.mix == ["pick_up_stiffness"]
