"""One action loop for every world.

A ``World`` executes primitive actions and tells what can be observed afterwards. The symbolic world of the task
plugins and the physical world (MuJoCo + renderer, ``muble.episode.physical``) both run through ``run_episode``,
so loop and timeout detection and the failure taxonomy are the same for both.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol

from muble.core.errors import PhysicsError, PlanningError
from muble.core.interfaces import Agent, Instruction
from muble.core.scene import SceneGraph
from muble.core.types import ActionCall, ActionResult, Answer, Observation, Outcome


class World(Protocol):
    """What the action loop needs of a world."""

    def observe(self, result: ActionResult | None, step: int) -> Observation:
        """The observation after an action (``result`` is None at the start)."""

    def apply(self, action: ActionCall) -> ActionResult:
        """Execute one primitive; raise ``PhysicsError`` if the simulation breaks."""


@dataclass
class EpisodeMonitor:
    """Turns the course of an episode into the failure taxonomy: loops, time-outs, failed actions."""

    max_steps: int = 100
    max_repeats: int = 3  # the same action from the same observed state this often is a loop
    seen: dict[tuple, int] = field(default_factory=dict)
    steps: int = 0

    @staticmethod
    def state_key(scene: SceneGraph) -> tuple:
        return tuple((o.id, tuple(round(float(v), 2) for v in o.position),
                      tuple(bool(o.extra.get(f)) for f in ("in_hand", "raised", "approached", "gripper_over")),
                      o.weight is not None) for o in scene.objects)

    def before(self, scene: SceneGraph, action: ActionCall) -> Outcome | None:
        """Call with the scene the agent decided on, before executing ``action``."""
        self.steps += 1
        key = (self.state_key(scene), str(action))
        self.seen[key] = self.seen.get(key, 0) + 1
        if self.seen[key] > self.max_repeats:
            return Outcome.LOOP_DETECTED
        if self.steps > self.max_steps:
            return Outcome.TIMEOUT
        return None

    @staticmethod
    def after(result: ActionResult) -> Outcome | None:
        """Call with the primitive's result."""
        return None if result.success else Outcome.EXECUTION_ERROR


@dataclass
class StepRecord:
    """One executed primitive and what was observed after it."""

    action: ActionCall
    result: ActionResult
    observation: Observation


@dataclass
class EpisodeResult:
    outcome: Outcome
    actions: list[ActionCall]
    answer: Answer | None
    final_scene: SceneGraph
    steps: list[StepRecord] = field(default_factory=list)
    initial: Observation | None = None
    error: str | None = None


Judge = Callable[[Instruction, SceneGraph, Answer | None], Outcome]


def run_episode(instruction: Instruction, world: World, agent: Agent, judge: Judge, max_steps: int = 100,
                max_repeats: int = 3, on_step: Callable[[StepRecord], None] | None = None) -> EpisodeResult:
    """Let ``agent`` act in ``world`` until it stops; the final state is judged by ``judge`` (a task's check)."""
    monitor = EpisodeMonitor(max_steps=max_steps, max_repeats=max_repeats)
    observation = world.observe(None, 0)
    initial = observation
    agent.reset(instruction, observation)
    actions: list[ActionCall] = []
    steps: list[StepRecord] = []
    answer: Answer | None = None

    def finish(outcome: Outcome, error: str | None = None) -> EpisodeResult:
        return EpisodeResult(outcome, actions, answer, observation.scene, steps, initial, error)

    while True:
        try:
            decision = agent.act(instruction, observation)
        except PlanningError as e:  # the agent's program cannot be carried out in this scene
            return finish(Outcome.PROGRAM_FAILURE, str(e))
        if decision is None:
            break
        if isinstance(decision, Answer):
            answer = decision
            continue
        failure = monitor.before(observation.scene, decision)
        if failure is not None:
            return finish(failure)
        try:
            result = world.apply(decision)
        except PhysicsError as e:
            return finish(Outcome.BROKEN_SCENE, str(e))
        actions.append(decision)
        observation = world.observe(result, len(actions))
        steps.append(StepRecord(decision, result, observation))
        if on_step is not None:
            on_step(steps[-1])
        failure = monitor.after(result)
        if failure is not None:
            return finish(failure, result.failure_reason)
    return finish(judge(instruction, observation.scene, answer))
