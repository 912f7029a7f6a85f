"""The benchmark's contracts in the action loop: what an agent may see, invalid calls, the closed loop.

Symbolic episodes here; the same checks run with physics in ``test_episode_integrity_physics.py`` and
``tests/tasks/test_tasks_oracle_physics.py``.
"""
from __future__ import annotations

import copy

import numpy as np
import pytest

from muble import ActionCall, ActionResult, Agent, Answer, Instruction, Observation, Outcome, get_registry
from muble.core import physical_properties
from muble.core.observation import agent_view, leaks
from muble.episode import run_episode
from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.success import check
from muble_plugins.common.symbolic import SymbolicWorld
from muble_plugins.common.synthetic import sample_scene

from tests.episode.probes import INVALID_CALLS, FailingWorld, Scripted, Snoop, hidden_values

# Every registered template (the stiffness and physical families included), so a new one is covered by the snooping test.
TEMPLATES = tuple(get_registry().names("task"))


def instruction_for(template: str, seed: int = 0, tries: int = 200):
    task = get_registry().create("task", template, {})
    for index in range(tries):
        scene = sample_scene(np.random.default_rng([seed, index]), index,
                             properties_rng=np.random.default_rng([seed, index, 6]))
        found = task.generate(scene, np.random.default_rng([seed, index, 1]))
        if found:
            return task, found[0], scene
    raise AssertionError(f"no {template} instruction in {tries} synthetic scenes")


@pytest.fixture(scope="module")
def episodes():
    return {t: instruction_for(t) for t in TEMPLATES}


@pytest.mark.parametrize("template", TEMPLATES)
def test_agent_sees_no_ground_truth_and_only_its_own_measurements(episodes, template):
    task, ins, scene = episodes[template]
    # A scene file whose weights and stiffness are filled in, and hidden physical properties: none of it may reach
    # the agent. A scene without the latter gets all three on every object (values no other field holds); one with
    # them keeps its own, which its instruction was made for.
    scene = copy.deepcopy(scene)
    carried = bool(hidden_values(scene))
    for o in scene.objects:
        o.weight = o.weight_gt + 1.0  # every object has a ground-truth stiffness too
        o.extra["friction"] = 0.7
        if not carried:
            o.extra.update({physical_properties.FRICTION: 0.4137 + o.id / 1000, physical_properties.COM_OFFSET:
                            [0.01237 + o.id / 10000, -0.00711], physical_properties.CONTENTS: 21.37 + o.id})
    snoop = Snoop(OracleAgent(), hidden_values(scene))
    result = run_episode(ins, SymbolicWorld(scene), snoop, check)
    assert result.outcome is Outcome.SUCCESS, result.error
    assert snoop.seen >= 2 and snoop.found == [], snoop.found
    # The ground truth stays with the record: the judge's scene still has every true weight.
    assert all(o.weight_gt is not None for o in result.final_scene.objects)
    if template.startswith("measure_weight"):
        assert snoop.weights_seen, "a weight measured by the agent is shown to it afterwards"


def test_the_snoop_finds_a_hidden_physical_property_anywhere_but_in_a_measurement_of_its_own():
    scene = sample_scene(np.random.default_rng(0), 0)
    scene.objects[0].extra.update({physical_properties.FRICTION: 0.4137, physical_properties.COM_OFFSET:
                                   [0.01237, -0.00711], physical_properties.CONTENTS: 21.37})
    secrets = hidden_values(scene)
    assert secrets == {0.4137, 0.01237, -0.00711, 21.37}
    ins = Instruction("Pick up the mug.", [], "pick_up", "pick_up")

    def found(observation) -> list[str]:
        snoop = Snoop(Scripted([]), secrets)
        snoop.reset(ins, observation)
        return snoop.found

    assert found(Observation(scene=agent_view(scene))) == []
    assert {"key 'friction_coefficient'", "key 'com_offset'", "key 'contents_g'",
            "the hidden value 21.37"} <= set(found(Observation(scene=scene)))
    # A value under another name, in a sensor's reading or a result's info, is found by its value.
    assert found(Observation(scene=agent_view(scene), measurements={"load": {0: [1.0, 21.37]}})) == [
        "the hidden value 21.37"]
    assert found(Observation(scene=agent_view(scene), last_result=ActionResult(True, info={"mu": 0.4137}))) == [
        "the hidden value 0.4137"]
    # The agent's own measurement (push on the object in its hand) is its to see.
    held = agent_view(scene)
    held.objects[0].extra["in_hand"] = True
    snoop = Snoop(Scripted([ActionCall("push")]), secrets)
    snoop.reset(ins, Observation(scene=held))
    assert snoop.act(ins, Observation(scene=held)) == ActionCall("push")
    pushed = agent_view(scene, {0: {"friction": 0.4137}})
    pushed.objects[0].extra["in_hand"] = True
    snoop.act(ins, Observation(scene=pushed, last_result=ActionResult(True, measurement=0.4137), step=1))
    assert snoop.seen == 2 and snoop.found == [], snoop.found


def test_leaks_finds_what_agent_view_removes(episodes):
    _, _, scene = episodes["stack_simple"]
    assert leaks(scene)  # the ground-truth scene is not an agent's view
    measured = {scene.objects[0].id: {"weight": 123.0, "stiffness": 900.0}}
    view = agent_view(scene, measured, hidden=("material",))
    assert leaks(view, measured) == []
    assert view.objects[0].weight == 123.0 and view.objects[0].extra["stiffness_measured"] == 900.0
    assert view.objects[1].weight is None and view.objects[1].weight_gt is None
    assert all(o.material is None for o in view.objects)  # an object set's hidden property
    assert leaks(view, {}) != []  # a weight the agent did not measure is a leak


@pytest.mark.parametrize("call", INVALID_CALLS, ids=[repr(c)[:40] for c in INVALID_CALLS])
def test_invalid_actions_are_the_agents_fault_in_the_symbolic_world(episodes, call):
    task, ins, scene = episodes["stack_simple"]
    result = run_episode(ins, SymbolicWorld(scene), Scripted([call]), check)
    assert result.outcome is Outcome.INVALID_ACTION, (result.outcome, result.error)
    assert result.error and result.actions == []


def test_at_least_twenty_kinds_of_invalid_calls():
    assert len(INVALID_CALLS) >= 20


def test_an_agent_that_raises_ends_its_episode_not_the_run(episodes):
    class Raising(Agent):
        def act(self, instruction, observation):
            raise ZeroDivisionError("bug in the agent")

    task, ins, scene = episodes["move_single"]
    result = run_episode(ins, SymbolicWorld(scene), Raising(), check)
    assert result.outcome is Outcome.AGENT_ERROR and "ZeroDivisionError" in result.error


@pytest.mark.parametrize("template,primitive", [("stack_simple", "approach"), ("move_single", "lower"),
                                                ("measure_weight_single", "close_gripper"),
                                                ("stack_weight", "move")])
def test_the_oracle_recovers_from_a_failed_primitive(episodes, template, primitive):
    task, ins, scene = episodes[template]
    world = FailingWorld(SymbolicWorld(scene), primitive, fail=2)
    result = run_episode(ins, world, OracleAgent(), check)
    assert result.outcome is Outcome.SUCCESS, (result.outcome, result.error)
    assert result.failures == 2
    retries = [c for c in world.calls if c.params.get("attempt")]
    assert retries, "the oracle retried differently (with another attempt)"


def test_failures_are_reported_and_the_episode_goes_on_until_the_budget(episodes):
    task, ins, scene = episodes["stack_simple"]
    # weigh with an empty hand fails every time; each call differs so it is no loop
    calls = [ActionCall("lift", {"height": 0.05 + 0.01 * k}) for k in range(20)]
    agent = Scripted(calls)
    result = run_episode(ins, SymbolicWorld(scene), agent, check, max_failures=5)
    assert result.outcome is Outcome.EXECUTION_ERROR and result.failures == 5
    assert all(not r.success for r in agent.results[1:])  # the agent was told about each failure
    assert "lift" in result.error


def test_final_state_is_judged_on_ground_truth_not_on_what_the_agent_saw(episodes):
    task, ins, scene = episodes["measure_weight_single"]
    truth = ins.program[-1]["output"]

    class Guess(Agent):
        def act(self, instruction, observation):
            if getattr(self, "done", False):
                return None
            self.done = True
            return Answer([o.weight for o in observation.scene.objects][:len(truth)])

    result = run_episode(ins, SymbolicWorld(scene), Guess(), check)
    assert result.outcome is Outcome.INCORRECT_ANSWER  # it saw no weight, so it could not copy one


def test_a_malformed_call_prints_as_it_came():
    """Logged and reported, an agent's call with parameters that are no mapping names them, never raises."""
    assert str(ActionCall("lift", [0.1])) == "lift(params=[0.1])"
    assert str(ActionCall("approach", {"target": 3})) == "approach(target=3)"
