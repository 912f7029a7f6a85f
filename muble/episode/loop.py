"""One action loop for every world.

A ``World`` executes primitive actions and tells what can be observed afterwards. The symbolic world of the task
plugins and the physical world (MuJoCo + renderer, ``muble.episode.physical``) both run through ``run_episode``,
so call checking, loop and timeout detection and the failure taxonomy are the same for both.

The loop is closed: a primitive that fails is reported to the agent (``Observation.last_result`` with its reason)
and the episode goes on, so the agent may recover; it ends when the agent answers and stops, says it is done
(``None``), repeats itself (``loop_detected``), runs out of steps (``timeout``) or of failures
(``execution_error`` after ``max_failures`` failed primitives). A call that no primitive accepts (unknown name or
parameter, a missing or mistyped one, a target not in the scene) ends it at once as ``invalid_action``; an agent
that raises ends it as ``agent_error`` (its traceback logged and kept in the result), and one that takes longer
than ``decision_timeout`` to decide ends it as ``timeout`` (``AgentCalls``). Agents see ``World.observe``'s scene
(what they may know, see ``muble.core.observation``); the judge and the records get ``World.ground_truth()``.
"""
from __future__ import annotations

import functools
import logging
import queue
import traceback
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol

from muble.core.errors import MubleError, PhysicsError, PlanningError
from muble.core.interfaces import Agent, Instruction, Task, reset_agent
from muble.core.observation import agent_instruction
from muble.core.scene import SceneGraph
from muble.core.types import ActionCall, ActionResult, Answer, Observation, Outcome, Track
from muble.episode.modes import ObservationView, check_track, express_with_pixels, resolve_pixels, track_instruction

log = logging.getLogger(__name__)

class World(Protocol):
    """What the action loop needs of a world."""

    def observe(self, result: ActionResult | None, step: int) -> Observation:
        """The observation after an action (``result`` is None at the start)."""

    def apply(self, action: ActionCall) -> ActionResult:
        """Execute one primitive; raise ``PhysicsError`` if the simulation breaks."""

    def ground_truth(self) -> SceneGraph:
        """The scene as it really is now (ground truth included), for the judge and the records."""


# Primitives an episode may execute before it ends as a timeout, where nothing else says: the default of
# ``episode.max_steps`` (muble.app.config) and of the symbolic roll-outs that make ground-truth plans and train the
# learned planner, so a plan the generator accepts fits in an episode.
DEFAULT_MAX_STEPS = 100


@dataclass
class EpisodeMonitor:
    """Turns the course of an episode into the failure taxonomy: loops and time-outs."""

    max_steps: int = DEFAULT_MAX_STEPS
    max_repeats: int = 3  # the same action from the same observed state this often is a loop
    seen: dict[tuple, int] = field(default_factory=dict)
    steps: int = 0

    @staticmethod
    def state_key(scene: SceneGraph) -> tuple:
        """What an observed state is, for telling a loop: each object's place (to the centimetre), the hand's flags
        and the weight read of it last (to a tenth of a gram, None before any). A noisy sensor's readings of one
        object differ (four alike to a tenth of a gram among a dozen readings of 9.6 g spread: about once in 100,000
        episodes), so weighing it again and again to decide a comparison is no loop; an exact sensor's do not."""
        return tuple((o.id, tuple(round(float(v), 2) for v in o.position),
                      tuple(bool(o.extra.get(f)) for f in ("in_hand", "raised", "approached", "gripper_over")),
                      None if o.weight is None else round(float(o.weight), 1)) for o in scene.objects)

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


@dataclass
class StepRecord:
    """One executed primitive, what the agent observed after it and the ground truth at that moment."""

    action: ActionCall
    result: ActionResult
    observation: Observation
    scene_gt: SceneGraph | None = None


@dataclass
class EpisodeResult:
    """How an episode went. ``final_scene`` and ``initial_gt`` are ground truth; ``initial`` and the steps'
    ``observation`` are what the agent saw."""

    outcome: Outcome
    actions: list[ActionCall]
    answer: Answer | None
    final_scene: SceneGraph
    steps: list[StepRecord] = field(default_factory=list)
    initial: Observation | None = None
    error: str | None = None
    initial_gt: SceneGraph | None = None
    failures: int = 0  # primitives that failed (reported to the agent)
    traceback: str | None = None  # agent_error: where the agent raised (its formatted traceback)


Judge = Callable[[Instruction, SceneGraph, Answer | None], Outcome]
"""A judge as a function: (instruction, final ground-truth scene, answer) -> outcome."""
# Why an action call is invalid in a scene (None: valid); see ``registry_call_check``.
CallCheck = Callable[[ActionCall, SceneGraph], "str | None"]
"""Why an action call is invalid in a scene, or None when it is valid (``registry_call_check`` makes one)."""


def _declared(action: Any, registry: Any = None) -> tuple:
    """The declared parameters of ``action``'s primitive (empty if it names none)."""
    if registry is None:
        from muble.plugins.registry import get_registry

        registry = get_registry()
    name = getattr(action, "name", None)
    if not isinstance(name, str) or name not in registry.names("primitive"):
        return ()
    return tuple(registry.get("primitive", name).record.factory.params)


def registry_call_check(registry: Any = None) -> CallCheck:
    """Checks calls against the registered primitives' declared parameters (``muble.core.params``)."""
    from muble.core.params import check_call

    if registry is None:
        from muble.plugins.registry import get_registry

        registry = get_registry()
    names = registry.names("primitive")

    def check(action: ActionCall, scene: SceneGraph) -> str | None:
        if not isinstance(action.name, str) or action.name not in names:
            return f"unknown primitive {action.name!r:.60}; registered primitives: {', '.join(names)}"
        declared = registry.get("primitive", action.name).record.factory.params
        return check_call(action.name, declared, action.params, scene.ids)

    return check


class DecisionTimeout(MubleError):
    """An agent's ``reset`` or ``act`` did not return within the time limit of one decision."""


class AgentCalls:
    """Calls an agent's ``reset`` and ``act`` with a time limit per call (``limit`` s; 0: none, on the caller's
    thread). With a limit every call of an episode runs on one worker thread of its own (an agent that keeps
    thread-bound state still finds it), and one that overruns raises ``DecisionTimeout``: the call is abandoned
    (interrupted at its next Python instruction; Python cannot stop a thread otherwise) and the episode ends."""

    def __init__(self, limit: float = 0.0):
        from muble.episode.stepped import EpisodeThread

        self.limit = float(limit or 0.0)
        self.worker = EpisodeThread(name="muble-agent") if self.limit > 0 else None

    def __call__(self, what: str, fn: Callable[[], Any]) -> Any:
        if self.worker is None:
            return fn()
        try:
            return self.worker.call(fn, timeout=self.limit)
        except queue.Empty:
            self.worker.interrupt()
            self.worker = None
            raise DecisionTimeout(f"{what} took longer than {self.limit:g} s (evaluation.decision_timeout): the "
                                  "decision was abandoned") from None

    def close(self) -> None:
        if self.worker is not None:
            self.worker.close()


def _agent_error(what: str, e: BaseException) -> str:
    """An agent's exception for the record, its traceback into the log (whose fault: the agent's; how to find
    it: the traceback)."""
    log.warning("%s raised %s: %s", what, type(e).__name__, e, exc_info=e)
    return f"{what} raised {type(e).__name__}: {e}"


def run_episode(instruction: Instruction, world: World, agent: Agent, judge: "Task | Judge",
                max_steps: int = DEFAULT_MAX_STEPS,
                max_repeats: int = 3, on_step: Callable[[StepRecord], None] | None = None,
                max_failures: int = 8, check_call: CallCheck | None = None, track: str = "program",
                mode: str = "graph", decision_timeout: float = 0.0) -> EpisodeResult:
    """Let ``agent`` act in ``world`` until it stops; the episode is judged by ``judge``: a ``Task`` (its ``judge``
    gets the whole record) or a function of (instruction, final ground-truth scene, answer).

    ``track`` and ``mode`` say what the agent is told (``muble.episode.modes``), and ``Agent.reset`` tells it
    both: the world's observation is the graph view with its frames; the agent gets the mode's view of it, and its
    object arguments are read in the mode's form (pixels in ``image`` mode). A privileged agent gets the program
    and the graph view (and is told the program track and graph mode).

    ``decision_timeout`` (s; 0: none) bounds each call of the agent's ``reset`` and ``act``: one that does not
    return in time ends the episode as ``timeout`` (``AgentCalls``). An agent that raises ends it as
    ``agent_error``, its traceback in the log and in the result's ``traceback``.
    """
    check_call = check_call or registry_call_check()
    privileged = bool(getattr(agent, "privileged", False))
    # What the agent is given; the judge gets the whole record.
    told = agent_instruction(instruction) if privileged else track_instruction(instruction, track)
    view = ObservationView("graph" if privileged else mode)
    pixels = mode == "image"
    monitor = EpisodeMonitor(max_steps=max_steps, max_repeats=max_repeats)
    observation = world.observe(None, 0)
    seen = view(observation)
    initial, initial_gt = observation, world.ground_truth()
    actions: list[ActionCall] = []
    steps: list[StepRecord] = []
    answer: Answer | None = None
    failures = 0
    last_failure: str | None = None

    def finish(outcome: Outcome, error: str | None = None) -> EpisodeResult:
        if outcome is not Outcome.SUCCESS and error is None:
            error = last_failure
        return EpisodeResult(outcome, actions, answer, world.ground_truth(), steps, initial, error, initial_gt,
                             failures)

    def agent_failed(what: str, e: Exception) -> EpisodeResult:
        if isinstance(e, DecisionTimeout):
            log.warning("%s", e)
            return finish(Outcome.TIMEOUT, str(e))
        failed = finish(Outcome.AGENT_ERROR, _agent_error(what, e))
        failed.traceback = "".join(traceback.format_exception(e))
        return failed

    calls = AgentCalls(decision_timeout)
    try:
        try:
            calls("agent.reset", lambda: reset_agent(agent, told, seen, mode=view.mode,
                                                     track=Track.program if privileged else check_track(track)))
        except Exception as e:  # noqa: BLE001 - whatever an agent raises ends its episode, never the evaluation
            return agent_failed("agent.reset", e)
        while True:
            try:
                decision = calls("agent.act", functools.partial(agent.act, told, seen))
            except PlanningError as e:  # the agent's program cannot be carried out in this scene
                return finish(Outcome.PROGRAM_FAILURE, str(e))
            except Exception as e:  # noqa: BLE001 - see above
                return agent_failed("agent.act", e)
            if decision is None:
                break
            if isinstance(decision, Answer):
                answer = decision
                continue
            if not isinstance(decision, ActionCall):
                return finish(Outcome.INVALID_ACTION, f"the agent returned {type(decision).__name__} "
                                                      f"{decision!r:.80}; return an ActionCall, an Answer or None")
            if pixels:
                declared = _declared(decision)
                if privileged:
                    decision = express_with_pixels(decision, observation, declared)
                decision = resolve_pixels(decision, observation, declared)
                if isinstance(decision, str):
                    log.info("invalid action: %s", decision)
                    return finish(Outcome.INVALID_ACTION, decision)
            problem = check_call(decision, observation.scene)
            if problem is not None:
                log.info("invalid action %s: %s", decision, problem)
                return finish(Outcome.INVALID_ACTION, problem)
            failure = monitor.before(observation.scene, decision)
            if failure is not None:
                return finish(failure)
            try:
                result = world.apply(decision)
            except PhysicsError as e:
                return finish(Outcome.BROKEN_SCENE, str(e))
            actions.append(decision)
            observation = world.observe(result, len(actions))
            seen = view(observation)
            steps.append(StepRecord(decision, result, observation, world.ground_truth()))
            if on_step is not None:
                on_step(steps[-1])
            if not result.success:
                failures += 1
                last_failure = f"{decision}: {result.failure_reason}"
                if failures >= max_failures:
                    return finish(Outcome.EXECUTION_ERROR,
                                  f"{failures} primitives failed, the last {last_failure}")
        record = finish(Outcome.SUCCESS)  # the record as the judge sees it; its outcome is the judge's
        record.outcome = judge.judge(instruction, record) if isinstance(judge, Task) else \
            judge(instruction, record.final_scene, answer)
        record.error = None if record.outcome is Outcome.SUCCESS else last_failure
        return record
    finally:
        calls.close()
