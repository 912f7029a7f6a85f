"""Episode bookkeeping shared by every action loop: loop and timeout detection, and symbolic roll-outs.

``EpisodeMonitor`` turns what happens during an episode into the failure taxonomy (execution error, loop,
timeout); the final state is judged by the task's ``check``. ``run_symbolic_episode`` plays an agent against
the symbolic world: ground-truth plans come from it, and it tests agents without physics.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from muble import ActionCall, ActionResult, Agent, Answer, Instruction, Observation, Outcome, PlanningError, SceneGraph

from muble_plugins.tasks.success import check
from muble_plugins.tasks.symbolic import SymbolicWorld


@dataclass
class EpisodeMonitor:
    """Watches the action loop. ``before`` and ``after`` return a failure outcome as soon as the episode must stop."""

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
class EpisodeResult:
    outcome: Outcome
    actions: list[ActionCall]
    answer: Answer | None
    final_scene: SceneGraph


def run_symbolic_episode(instruction: Instruction, scene: SceneGraph, agent: Agent,
                         max_steps: int = 100) -> EpisodeResult:
    """Play ``agent`` on ``instruction`` in a symbolic copy of ``scene`` and judge the outcome."""
    world = SymbolicWorld(scene)
    monitor = EpisodeMonitor(max_steps=max_steps)
    observation = Observation(scene=world.scene)
    agent.reset(instruction, observation)
    actions: list[ActionCall] = []
    answer: Answer | None = None
    while True:
        try:
            decision = agent.act(instruction, observation)
        except PlanningError:
            return EpisodeResult(Outcome.PROGRAM_FAILURE, actions, answer, world.scene)
        if decision is None:
            break
        if isinstance(decision, Answer):
            answer = decision
            observation = Observation(scene=world.scene, step=observation.step + 1)
            continue
        failure = monitor.before(world.scene, decision)
        if failure is not None:
            return EpisodeResult(failure, actions, answer, world.scene)
        result = world.apply(decision)
        actions.append(decision)
        failure = monitor.after(result)
        if failure is not None:
            return EpisodeResult(failure, actions, answer, world.scene)
        observation = Observation(scene=world.scene, last_result=result, step=observation.step + 1)
    return EpisodeResult(check(instruction, world.scene, answer), actions, answer, world.scene)
