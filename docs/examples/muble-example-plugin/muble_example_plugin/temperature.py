"""A hidden property of one's own: how warm an object is, and ``feel``, the primitive that measures it.

The property is one ``muble.Property`` record (``TEMPERATURE``), registered with ``muble_register_properties``
(``__init__.py``). From it MuBlE derives everything per property: the program steps ``query_temperature``,
``filter_temperature`` (warmest, coldest) and ``order_temperature``, the template word domain
``temperature_superlative`` and the constraint ``temperature_extreme`` (values apart by the 5 °C margin), the
answer check (within 1 °C), the agent view's key ``extra["temperature_measured"]``, the task planner's measuring
plan (grasp the object, then ``feel``) and the scene generator's sampler, drawn from the stream
``scene.temperature`` for ``generator.physical_properties=[temperature]`` into each scene object's
``extra["temperature_c"]``.

Which objects carry it: the pickupable food and drink containers of the SHOP-VRB2 object set, by category. A
thermal probe in a fingertip needs an object the hand can close around (``feel`` needs it grasped), and a
temperature worth asking about is that of something served hot or cold; in SHOP-VRB2 the two coincide (every
pickupable category is a bowl, glass, mug, soda can, thermos or wine glass), while a plate, a chopping board or
another object set's tool gets none. Every other object stands at the room's temperature, ``AMBIENT_C``.

Written against MuBlE's public API only (docs/plugins.md, "The public API").
"""
from __future__ import annotations

import math

import numpy as np

import muble
from muble import ActionResult, SceneGraph
from muble.core.symbolic import ArmState

SCENE_KEY = "temperature_c"  # where a scene object keeps its true temperature (``SceneObject.extra``)
RANGE_C = (4.0, 60.0)  # drawn uniformly: from the fridge to a hot drink
AMBIENT_C = 22.0  # the room, and so the probe before it touches anything, and an object that carries none
TOLERANCE_C = 1.0  # an answered temperature within this of the true one is right
MARGIN_C = 5.0  # templates compare temperatures at least this far apart (more than twice the tolerance)
# The categories whose objects carry a temperature: the SHOP-VRB2 food and drink containers the hand can hold.
CONTAINERS = ("bowl", "glass", "mug", "soda can", "thermos", "wine glass")

PROBE_TIME_CONSTANT_S = 0.4  # the fingertip probe's first-order response to what it touches
FEEL_HOLD_S = 2.0  # how long the fingers hold the object while the probe settles (5 time constants)


def sample_temperature(rng: np.random.Generator, model, weight_g: float) -> float:
    """A temperature (°C) uniform in ``RANGE_C``, 1 decimal: one draw from the property's stream."""
    return round(float(rng.uniform(*RANGE_C)), 1)


def holds_food_or_drink(spec, model) -> bool:
    """Whether an object (its ``ObjectSpec`` and built ``ObjectModel``) carries a temperature: a pickupable one of
    ``CONTAINERS``."""
    return bool(model.pickupable) and spec.category in CONTAINERS


def true_temperature(obj: muble.SceneObject) -> float | None:
    """The object's true temperature (°C), or None where its scene gives none."""
    value = obj.extra.get(SCENE_KEY)
    return None if value is None else float(value)


TEMPERATURE = muble.Property(
    "temperature", "feel", true_temperature, "how warm the object is (°C)", unit="°C", needs="grasped",
    superlatives=("warmest", "coldest"), tolerance=TOLERANCE_C, margin=MARGIN_C,
    sampled_as="temperature", scene_key=SCENE_KEY, sampler=sample_temperature, carried_by=holds_food_or_drink)


def probe_step(probe: float, target: float, dt: float, touching: bool) -> float:
    """The probe's temperature after ``dt`` seconds: relaxed towards ``target`` with ``PROBE_TIME_CONSTANT_S``
    while it touches the object, unchanged while it does not (the exact solution of the first-order law over the
    step, so the result does not depend on the physics step)."""
    if not touching:
        return probe
    return target + (probe - target) * math.exp(-dt / PROBE_TIME_CONSTANT_S)


class Feel(muble.PrimitiveAction):
    """Temperature (°C) of the object between the fingers, read by a thermal probe in a fingertip.

    The fingers keep holding the object (grasped, lifted or standing) for ``FEEL_HOLD_S`` seconds. The probe starts
    at the room's temperature and, on every physics step on which a finger really touches the object in MuJoCo
    (``env.finger_contacts``), relaxes towards the object's temperature with ``PROBE_TIME_CONSTANT_S``; while no
    finger touches it, it stays where it is. The reading is the probe's temperature at the end, 0.1 °C. MuJoCo
    simulates no heat: the object's temperature is the world's state, as the scene gives it (its ground truth,
    ``env.sync_scene_graph()``); what the primitive simulates is the probe, and the reading is only as good as the
    contact it had.
    """

    params = ()
    measures = "temperature"
    measure_unit = "°C"
    empty_hand = "nothing between the fingers to feel: grasp an object first"

    def execute(self, env) -> ActionResult:
        held = env.held_object
        if held is None:
            return ActionResult(False, failure_reason=self.empty_hand)
        if not any(True for _ in env.finger_contacts(held)):
            return ActionResult(False, failure_reason=f"the fingers do not touch object {held}: grasp it again")
        world = true_temperature(env.sync_scene_graph().object(held))
        target = AMBIENT_C if world is None else world
        dt = float(env.model.opt.timestep)
        probe, touched = AMBIENT_C, 0

        def on_physics() -> None:
            nonlocal probe, touched
            touching = any(True for _ in env.finger_contacts(held))
            probe = probe_step(probe, target, dt, touching)
            touched += touching

        env.advance(FEEL_HOLD_S, on_physics=on_physics)
        reading = round(probe, 1)
        env.measurements.setdefault(held, {})[self.measures] = reading  # the agent's view shows it from now on
        return ActionResult(True, measurement=reading,
                            info={"object": held, "unit": self.measure_unit, "contact_s": round(touched * dt, 3)})

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        """The grasped object's temperature is known (lifted or standing, as in ``execute``): its ground truth
        (the room's where its scene gives none), recorded as measured (``extra["temperature_measured"]``)."""
        held = ArmState.of(scene).held_object(scene)
        if held is None:
            return ActionResult(False, failure_reason=self.empty_hand)
        value = true_temperature(held)
        value = AMBIENT_C if value is None else value
        held.extra[TEMPERATURE.measured_key] = value
        return ActionResult(True, measurement=value)
