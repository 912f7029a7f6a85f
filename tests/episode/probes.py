"""Probes for the action loop: an agent wrapper that checks every observation, scripted calls, invalid calls and
a world that fails on purpose."""
from __future__ import annotations

import dataclasses

import numpy as np

from muble import ActionCall, ActionResult, Agent, Answer
from muble.core import physical_properties
from muble.core.observation import leaks

# The scene keys of the hidden physical properties: no observation may carry them, under any name or nesting.
HIDDEN_KEYS = (physical_properties.FRICTION, physical_properties.COM_OFFSET, physical_properties.CONTENTS)
# What each measuring primitive reports, under the name ``leaks`` knows a measurement by.
MEASURES = {"weigh": "weight", "reweigh": "weight", "squeeze": "stiffness", "push": "friction", "balance": "com_offset",
            "shake": "rattles"}


def hidden_values(scene) -> set[float]:
    """Every non-zero number the scene's objects hold under ``HIDDEN_KEYS`` (a com offset's coordinates each)."""
    values = set()
    for o in scene.objects:
        for key in HIDDEN_KEYS:
            value = o.extra.get(key)
            values.update(float(v) for v in np.ravel([] if value is None else value) if float(v) != 0.0)
    return values


def keys_and_numbers(value, out: tuple[list, list] | None = None) -> tuple[list, list]:
    """Every mapping key and every number inside ``value`` (dataclasses, mappings, sequences, arrays of at most 16
    values: not images)."""
    keys, numbers = out if out is not None else ([], [])
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            keys_and_numbers(getattr(value, f.name), (keys, numbers))
    elif isinstance(value, dict):
        for k, v in value.items():
            keys.append(k)
            keys_and_numbers(v, (keys, numbers))
    elif isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.size <= 16):
        for v in value:
            keys_and_numbers(v, (keys, numbers))
    elif isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)):
        numbers.append(float(value))
    return keys, numbers


class Snoop(Agent):
    """Wraps an agent and checks each observation it gets: no ground truth, no weight or stiffness it did not
    measure, and, anywhere in it, none of the hidden physical properties' keys (``HIDDEN_KEYS``) and none of
    ``secrets`` (their values: ``hidden_values``) but as a measurement of its own."""

    def __init__(self, inner: Agent, secrets: set[float] = frozenset()):
        self.inner = inner
        self.secrets = set(secrets)
        self.found: list[str] = []
        self.seen = 0
        self.weights_seen = 0
        self.measured: dict[int, dict[str, float]] = {}
        self.last: ActionCall | None = None
        self.held: int | None = None

    def _inspect(self, observation) -> None:
        result = observation.last_result
        if self.last is not None and self.last.name in MEASURES and result is not None and result.success:
            self.measured.setdefault(self.held, {})[MEASURES[self.last.name]] = result.measurement
        self.held = next((o.id for o in observation.scene.objects if o.extra.get("in_hand")), None)
        self.seen += 1
        self.weights_seen += sum(o.weight is not None for o in observation.scene.objects)
        self.found += leaks(observation.scene, self.measured)
        for key, reading in observation.measurements.items():
            if key in ("weight", "stiffness"):
                for obj_id, value in reading.items():
                    if self.measured.get(obj_id, {}).get(key) != value:
                        self.found.append(f"sensor {key} reports object {obj_id} unmeasured")
        keys, numbers = keys_and_numbers(observation)
        self.found += [f"key '{k}'" for k in keys if k in HIDDEN_KEYS]
        _, mine = keys_and_numbers(self.measured)
        self.found += [f"the hidden value {v}" for v in numbers if v in self.secrets and v not in mine]

    def _inspect_instruction(self, instruction) -> None:
        if instruction.extra:
            self.found.append(f"instruction records {sorted(instruction.extra)}")
        if any("output" in step for step in instruction.program):
            self.found.append("the program's recorded outputs")
        for k, step in enumerate(instruction.program):
            if step.get("input") is not None:  # the previous step's result, computed on the ground truth
                self.found.append(f"step {k} ({step['type']}) input {step['input']}")

    def reset(self, instruction, observation, **told):
        self._inspect_instruction(instruction)
        self.measured, self.last, self.step = {}, None, 0
        self._inspect(observation)
        self.inner.reset(instruction, observation, **told)

    def act(self, instruction, observation):
        self._inspect_instruction(instruction)
        if observation.step and observation.step != self.step:  # a new observation (not the one answered on)
            self.step = observation.step
            self._inspect(observation)
        decision = self.inner.act(instruction, observation)
        self.last = decision if isinstance(decision, ActionCall) else self.last
        return decision


class Scripted(Agent):
    """Issues the given decisions in order, then stops; keeps the results it was told."""

    def __init__(self, decisions):
        self.decisions = list(decisions)
        self.results = []

    def reset(self, instruction, observation, **told):
        self.queue = list(self.decisions)
        self.results = [observation.last_result]

    def act(self, instruction, observation):
        if observation.step:
            self.results.append(observation.last_result)
        return self.queue.pop(0) if self.queue else None


# Calls no primitive accepts, of twenty-odd kinds: each must end the episode as the agent's fault.
INVALID_CALLS = [
    ActionCall("fly", {}),  # unknown primitive
    ActionCall(3, {}),  # name not a string
    ActionCall("approach", {}),  # missing target
    ActionCall("approach", {"target": "mug"}),  # a word, not an id
    ActionCall("approach", {"target": 99}),  # not in the scene
    ActionCall("approach", {"target": 1.5}),  # float id
    ActionCall("approach", {"target": True}),  # bool id
    ActionCall("approach", {"target": 0, "speed": 3}),  # unknown parameter
    ActionCall("approach", {"target": 0, "attempt": -1}),  # attempt out of range
    ActionCall("move", {"target": "nowhere"}),  # unknown table part
    ActionCall("move", {"target": None}),
    ActionCall("move", {}),
    ActionCall("lift", {"height": "high"}),
    ActionCall("lift", {"height": float("nan")}),
    ActionCall("lift", {"height": -1.0}),
    ActionCall("lift", {"height": 5.0}),  # beyond the arm's reach
    ActionCall("move_vel", {"velocity": [0.0, 0.0]}),  # wrong length
    ActionCall("move_vel", {"velocity": "up"}),
    ActionCall("move_vel", {"velocity": [0.0, 0.0, "a"]}),
    ActionCall("move_vel", {"velocity": [float("inf"), 0.0, 0.0]}),
    ActionCall("move_vel", {"velocity": [0.0, 0.0, 0.1], "duration": -2}),
    ActionCall("lower", {"target": [1, 2]}),
    ActionCall("close_gripper", {"target": {"id": 0}}),
    ActionCall("weigh", {"target": 0}),  # weigh takes no parameters
    ActionCall("lift", [0.1]),  # parameters not a mapping
    "lift",  # not an ActionCall at all
    Answer,  # a class, not an answer
]


class FailingWorld:
    """A world whose primitives fail the first ``fail`` times they are called with ``name``."""

    def __init__(self, inner, name: str, fail: int = 1):
        self.inner, self.name, self.fail = inner, name, fail
        self.calls: list[ActionCall] = []

    def observe(self, result, step):
        return self.inner.observe(result, step)

    def ground_truth(self):
        return self.inner.ground_truth()

    def apply(self, action):
        self.calls.append(action)
        if action.name == self.name and self.fail > 0:
            self.fail -= 1
            return ActionResult(False, failure_reason="injected failure")
        return self.inner.apply(action)
