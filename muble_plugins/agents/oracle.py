"""The oracle agent: the task's plan, replanned after every primitive."""
from __future__ import annotations

import copy
import dataclasses
import logging
import math
from dataclasses import dataclass

from muble import (ActionCall, Agent, Answer, Instruction, Observation, ObservationMode, PlanningError, SceneGraph,
                   Task, Track, get_registry)

from muble.core.ranges import bounded
from muble.core.symbolic import ArmState
from muble.episode.loop import DEFAULT_MAX_STEPS

from muble_plugins.common.books import (CERTAINTY, RETRY_LIMIT, Certainty, Known, Readings, book, fill_known,
                                        primitive_params)
from muble_plugins.common.symbolic import APPROACH

log = logging.getLogger(__name__)


@dataclass
class OracleConfig:
    # False: the open-loop control (docs/closed_loop.md): the plan is made once from the first observation and the
    # primitives' own expected effects, never re-checked against what is observed; a failed primitive is retried.
    closed_loop: bool = True
    # Standard deviation (g) of one weighing, as the wrist sensor's datasheet implies (docs/physical_properties.md,
    # "Noisy sensing", gives it for noise=wrist_ft). Above 0 the oracle weighs again, closed loop, until each weight
    # comparison it makes is decided (``books.Certainty``); 0: every reading is taken as exact, one decides.
    reading_noise_g: float = bounded(0.0, ge=0)
    # A comparison is decided when the means differ by more than this many standard errors of their difference.
    decide_sigmas: float = bounded(2.5, gt=0)
    # Readings of one object at most; then the means decide. Each further reading of the object in the hand is one
    # ``reweigh`` (``Property.again``); the action loop tells these apart by the weight each read
    # (muble.episode.loop.EpisodeMonitor), so no number of them is a loop.
    max_readings: int = bounded(24, ge=1)
    # Readings of one property in an episode at most, all objects together; then the means decide. 0: no bound
    # but the step budget's (below).
    max_readings_total: int = bounded(0, ge=0)
    # The episode's step budget (``episode.max_steps``: set both together). Every reading is a primitive: the oracle
    # weighs again only while the budget spares one beyond the rest of its plan (rolled out in the symbolic world,
    # as if every comparison were decided now) and ``step_reserve`` primitives for failures and their retries.
    step_budget: int = bounded(DEFAULT_MAX_STEPS, ge=1)
    step_reserve: int = bounded(10, ge=0)


class OracleAgent(Agent):
    """Solves any task that plans towards its goal (``Task.next_actions``), closed loop.

    After every primitive it asks the instruction's task (the registered task named by its ``template_id``, or
    the one it was built for) for the next primitives from the observed scene, with the hidden properties it
    measured so far (the scene's ``weight`` fields and ``extra["<property>_measured"]``, which hold only what this
    agent measured, and the results of the measuring primitives: weigh, squeeze, push, balance, shake), and takes
    the first; so a slipped grasp or a
    displaced object is simply planned around. The gripper's state comes from the scene's flags (``in_hand``,
    ``raised``, ``approached``, ``gripper_over``), which the symbolic and the physical world both report; a world
    without the hover flags has them filled in from the last primitive.

    After a failed primitive it starts that object's part of the plan over (the hover and grasp-pose flags
    forgotten) and retries differently: primitives that take an ``attempt`` get the number of failures so far on
    that target, so they start from their next-best grasp, place or hover pose.

    Privileged by definition: whatever the run's track and observation mode, it is given the program and the
    graph view, and its actions are put in the mode's form (pixel targets in ``image`` mode), so its success
    shows that each mode is solvable; it is never a contestant.

    With ``reading_noise_g`` above 0 (a noisy wrist sensor, ``noise=wrist_ft``) it keeps every weighing and uses
    their mean; a comparison of weights whose means are closer than the readings' scatter allows is not decided
    yet, and the less certain object is weighed again (set down and grasped again, so that a new tare makes the
    reading independent: ``reweigh`` does that in one primitive), up to ``max_readings`` each (``books.Certainty``);
    the object in the hand is read again first, as often as the comparison's gap asks. ``stats()`` then counts the
    readings.
    The open-loop control never weighs again: it decides on its first reading.
    """

    privileged = True

    def __init__(self, config: OracleConfig | None = None, task: Task | None = None) -> None:
        self.config = config if config is not None else OracleConfig()  # the registry's checked instance
        self.closed_loop = self.config.closed_loop
        self.belief: SceneGraph | None = None  # open loop: the world as planned, from the first observation on
        self.task = task
        self.tasks: dict[str, Task] = {}
        self.known: Known = {}  # what this agent's measuring primitives reported, by property and object
        self.readings: Readings = {}  # every reading behind ``known``, by property and object
        self.read_since_approach: int | None = None  # measured since the hand last approached (and tared)
        self.handled: object = None  # the last primitive's result once it has been taken into account
        self.answered = False
        self.last: ActionCall | None = None
        self.failures: dict[object, int] = {}  # failed primitives per target (object id, table part or None)
        self.rest: tuple[frozenset, int] | None = None  # the objects measured, the rest of the plan's length then

    def reset(self, instruction: Instruction, observation: Observation, *, track: Track = Track.program,
              mode: ObservationMode = ObservationMode.graph) -> None:
        self.known = {}
        self.readings = {}
        self.read_since_approach = None
        self.handled = None
        self.answered = False
        self.last = None
        self.failures = {}
        self.rest = None
        self.belief = None if self.closed_loop else copy.deepcopy(observation.scene)

    @property
    def remeasures(self) -> bool:
        """Whether this oracle weighs again until a comparison is decided: closed loop, with a noisy sensor."""
        return self.closed_loop and self.config.reading_noise_g > 0

    @property
    def stats(self):
        """The episode's counters (``muble.evaluation.episodes.agent_stats``) where this oracle weighs again:
        ``readings`` (every measurement booked), ``readings_again`` (those of an object and property measured
        before) and ``objects_at_limit`` (objects read ``max_readings`` times). None otherwise, so a run with an
        exact sensor records no counters, as before."""
        return self._counts if self.remeasures else None

    def _counts(self) -> dict[str, int]:
        per_object = [len(kept) for by_object in self.readings.values() for kept in by_object.values()]
        return {"readings": sum(per_object), "readings_again": sum(n - 1 for n in per_object),
                "objects_at_limit": sum(n >= self.config.max_readings for n in per_object)}

    def _task(self, instruction: Instruction) -> Task:
        if self.task is not None:
            return self.task
        if instruction.template_id not in self.tasks:
            self.tasks[instruction.template_id] = get_registry().create("task", instruction.template_id, {})
        return self.tasks[instruction.template_id]

    def _known(self, observation: Observation) -> Observation:
        """The observation with this agent's measurements and the gripper's hover state filled in."""
        scene = copy.deepcopy(observation.scene)
        fill_known(scene, self.known, self.last, observation.last_result, self.readings)
        return dataclasses.replace(observation, scene=scene)

    def _certainty(self, instruction: Instruction, observation: Observation) -> Certainty:
        """When a weight comparison counts as decided (``books.Certainty``), for a noisy sensor, closed loop."""
        return Certainty({"weight": self.config.reading_noise_g}, self.readings, self.config.decide_sigmas,
                         self.config.max_readings, self.read_since_approach, self.config.max_readings_total or None,
                         self._spare_steps(instruction, observation))

    def _spare_steps(self, instruction: Instruction, observation: Observation):
        """What ``Certainty`` asks before a reading: the primitives the step budget spares beyond the plan's rest
        (``plan_length``, worked out again only when another object has been measured) and the reserve."""
        def spare() -> int:
            measured = frozenset(obj for by_object in self.readings.values() for obj in by_object)
            if self.rest is None or self.rest[0] != measured:
                self.rest = (measured, self.plan_length(instruction, observation))
            return self.config.step_budget - observation.step - self.rest[1] - self.config.step_reserve
        return spare

    def plan_length(self, instruction: Instruction, observation: Observation) -> int:
        """The primitives the task's plan takes from ``observation`` to its end, were every comparison decided on
        the means so far: the plan rolled out in the symbolic world (each primitive's ``symbolic_effect``) on this
        agent's view, an object not yet measured taken at the mean weight of those that were. A roll-out that
        fails counts what it planned until then."""
        scene = self._known(observation).scene  # a copy, with no Certainty: every comparison decided now
        weights = [o.weight for o in scene.objects if o.weight is not None]
        guess = math.fsum(weights) / len(weights) if weights else 100.0
        for o in scene.objects:
            o.weight_gt = o.weight if o.weight is not None else guess
        task, registry = self._task(instruction), get_registry()
        done = 0
        while done < self.config.step_budget:
            try:
                step = task.next_actions(instruction, Observation(scene=scene, step=done))
            except PlanningError as e:
                log.warning("the plan's rest could not be rolled out (%s): counting %d primitives", e, done)
                return done
            if isinstance(step, Answer) or not step:
                return done
            for call in step:
                done += 1
                if not registry.create("primitive", call.name, call.params).symbolic_effect(scene).success:
                    log.warning("the plan's rest could not be rolled out (%s failed symbolically): counting %d "
                                "primitives", call, done)
                    return done
        return done

    def act(self, instruction: Instruction, observation: Observation) -> ActionCall | Answer | None:
        result = observation.last_result
        # Each result once: after an answer the loop asks again with the same observation, and a reading booked
        # twice would count as two.
        if self.last is not None and result is not None and result is not self.handled:
            self.handled = result
            if not result.success:
                key = self._target(self.last)
                self.failures[key] = self.failures.get(key, 0) + 1
                log.info("%s failed (%s); retrying differently", self.last, result.failure_reason)
            else:
                held = ArmState.of(observation.scene).held
                book(self.known, self.last, result, held, self.readings)
                if get_registry().measures(self.last.name) is not None:
                    self.read_since_approach = held
                elif self.last.name == APPROACH:
                    self.read_since_approach = None
                self._expect(self.last)
        if self.belief is not None:  # open loop: plan on the world as expected, not as observed
            observation = dataclasses.replace(observation, scene=self.belief)
        known = self._known(observation)
        if self.remeasures and self.belief is None:
            known.scene.extra[CERTAINTY] = self._certainty(instruction, observation)
        step = self._task(instruction).next_actions(instruction, known)
        if isinstance(step, Answer):
            if self.answered:
                return None
            self.answered = True
            return step
        self.last = self._retry(step[0]) if step else None
        return self.last

    def _expect(self, action: ActionCall) -> None:
        """Open loop: the belief takes the succeeded primitive's expected effect (its symbolic model); what a
        measuring primitive reports is in the books already."""
        if self.belief is None or get_registry().measures(action.name) is not None:
            return
        primitive = get_registry().create("primitive", action.name, action.params)
        expected = copy.deepcopy(self.belief)
        if primitive.symbolic_effect(expected).success:
            self.belief = expected

    @staticmethod
    def _target(action: ActionCall) -> object:
        return action.params.get("target")

    def _retry(self, action: ActionCall) -> ActionCall:
        """``action`` with ``attempt`` set to the failures on its target, where the primitive takes one."""
        attempt = min(self.failures.get(self._target(action), 0), RETRY_LIMIT)
        if attempt and "attempt" in primitive_params(action.name):
            return ActionCall(action.name, {**action.params, "attempt": attempt})
        return action
