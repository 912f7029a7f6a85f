"""The action loop's contracts with MuJoCo physics: invalid calls, recovery from a failed primitive, an end state
judged on contacts and uprightness rather than positions, and no hidden physical property shown in any mode."""
from __future__ import annotations

import numpy as np
import pytest

from muble import ActionCall, Instruction, Outcome, get_registry
from muble.core.physical_properties import CONTENTS, PROPERTIES
from muble.episode import run_episode
from muble.episode.physical import PhysicalWorld
from muble.sim.env import TabletopEnv
from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.success import check
from tests.support.scenes import simple_object_model, simple_scene

from tests.episode.probes import INVALID_CALLS, FailingWorld, Scripted, Snoop, hidden_values

pytestmark = pytest.mark.slow


def stack_instruction(top: int, base: int) -> Instruction:
    return Instruction(f"Put object {top} on object {base}.",
                       [{"type": "scene", "input": None, "input_value": None, "output": [top, base]},
                        {"type": "stack", "input": [0], "input_value": None, "output": [[top], [base]]}],
                       "stack_simple", "stack")


def platform_and_can(toppled: bool):
    """A wide low box (a stack base) with a can standing on it, or lying on its side on it."""
    base = simple_object_model("box", (0.25, 0.25, 0.02), 500.0)
    can = simple_object_model("cylinder", (0.05, 0.05, 0.10), 150.0)
    scene = simple_scene([(0.5, -0.05), (0.5, -0.05)], [base, can])
    scene.objects[1].position = np.array([0.5, -0.05, 0.02])
    if toppled:  # about x by 90 degrees: the axis lies along y, the body over the base's middle
        half = np.sqrt(0.5)
        scene.objects[1].orientation = np.array([half, half, 0.0, 0.0])
        scene.objects[1].position = np.array([0.5, -0.05, 0.02 + 0.025])
    return scene, {0: base, 1: can}


@pytest.mark.parametrize("toppled", [False, True])
def test_a_toppled_top_object_is_not_stacked(toppled):
    scene, models = platform_and_can(toppled)
    env = TabletopEnv(scene, models)
    try:
        env.hold(1.0)
        final = env.sync_scene_graph()
    finally:
        env.close()
    can = final.object(1)
    assert 0 in can.extra["touching"]  # it lies on the base either way: contact alone is not stacking
    # Positions alone would call both stacked: the can's origin is over the base's middle and above it.
    assert np.hypot(*(can.position[:2] - final.object(0).position[:2])) < 0.03
    outcome = check(stack_instruction(1, 0), final, None)
    assert outcome is (Outcome.SCENE_INCONSISTENCY if toppled else Outcome.SUCCESS), can.extra


@pytest.fixture(scope="module")
def physical_world():
    scene, models = platform_and_can(False)
    env = TabletopEnv(scene, models)
    world = PhysicalWorld(env, get_registry())
    yield world, stack_instruction(1, 0)
    env.close()


@pytest.mark.parametrize("call", INVALID_CALLS, ids=[repr(c)[:40] for c in INVALID_CALLS])
def test_invalid_actions_are_the_agents_fault_with_physics(physical_world, call):
    world, instruction = physical_world
    before = world.env.data.time
    result = run_episode(instruction, world, Scripted([call]), check)
    assert result.outcome is Outcome.INVALID_ACTION, (result.outcome, result.error)
    assert world.env.data.time == before  # rejected before anything ran


def test_the_oracle_recovers_from_a_forced_approach_failure_with_physics():
    from muble.io.scene_io import load_scene
    from muble.sim.build import env_from_object_set
    from pathlib import Path

    scene = load_scene(Path(__file__).parents[1] / "planning" / "data" / "can_into_a_bowl_on_a_bowl.json")
    task = get_registry().create("task", "stack_simple", {})
    instruction = next(i for k in range(20)
                       for i in task.generate(scene, np.random.default_rng([0, k, 1])))
    env = env_from_object_set(scene, "shopvrb2")
    try:
        world = FailingWorld(PhysicalWorld(env, get_registry()), "approach", fail=1)
        result = run_episode(instruction, world, OracleAgent(), task.check)
    finally:
        env.close()
    assert result.outcome is Outcome.SUCCESS, (result.outcome, result.error, [str(a) for a in result.actions])
    assert result.failures == 1
    approaches = [c for c in world.calls if c.name == "approach"]
    assert len(approaches) >= 2 and approaches[1].params.get("attempt") == 1


@pytest.mark.gl
def test_no_observation_mode_shows_the_hidden_physical_properties():
    """A generated scene whose objects carry every hidden physical property (a closed container with contents among
    them), built with every registered sensor and drawn by the MuJoCo renderer: in graph, masks and image mode no
    observation an agent gets holds their keys or their values."""
    from muble.generation import SceneGenerator
    from muble.sim.build import env_from_object_set
    from tests.generation.builtin import BUILTIN

    registry = get_registry()
    object_set = registry.create("object_set", "shopvrb2")
    generator = SceneGenerator({**BUILTIN, "reach_check": False, "physical_properties": list(PROPERTIES)}, seed=4,
                               object_set=object_set)
    try:
        scene = generator.generate(0)
    finally:
        generator.close()
    secrets = hidden_values(scene)
    assert any(o.extra.get(CONTENTS) for o in scene.objects) and len(secrets) >= 10, secrets
    renderer = registry.create("renderer", "mujoco", {"width": 160, "height": 120})
    try:
        for mode in ("graph", "masks", "image"):
            env = env_from_object_set(scene, object_set, sensors=registry.names("sensor"))
            try:
                renderer.setup(env.sync_scene_graph(), env.model)
                snoop = Snoop(Scripted([ActionCall("move", {"target": "left"}), ActionCall("lift")]), secrets)
                run_episode(stack_instruction(1, 0), PhysicalWorld(env, registry, renderer), snoop, check, mode=mode)
            finally:
                env.close()
            assert snoop.seen >= 3 and snoop.found == [], (mode, snoop.found)
    finally:
        renderer.close()
