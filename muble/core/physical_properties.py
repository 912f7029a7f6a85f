"""The hidden physical properties: one ``Property`` record each, registered by plugins, and the ground truth of the
three the scene generator draws (friction, centre of mass and loose contents).

A hidden property is what an agent learns only by acting: weight (``weigh``), stiffness (``squeeze``), friction
(``push``), the centre of mass (``balance``) and loose contents (``shake``) are MuBlE's own, registered by its
primitives plugin; a package adds one with ``muble_register_properties`` (docs/plugins.md, "Adding a hidden
property"). Everything that is per property (program steps and their words, the agent view's measured keys, the
answer checks, the comparison margins of templates, the task planner's measuring primitives, the scene
generator's samplers and streams) is read from the registered records (``registered``), so that adding one edits
nothing in MuBlE.

A scene object carries the ground truth of a sampled property in ``SceneObject.extra`` under its ``scene_key``; an
agent never sees it (the agent view is an allow-list, ``muble.core.observation``). ``muble.sim.build.object_models``
builds the built-in three into the object's ``ObjectModel``; without them the object is simulated exactly as
before. The scene generator draws a property (``Property.sampler``, from its stream ``scene.<sampled_as>``) for the
objects that carry it when its ``physical_properties`` option names it (docs/scene_generation.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Mapping

import numpy as np

from muble.core.errors import SceneValidationError
from muble.core.scene import SceneObject

FRICTION = "friction_coefficient"  # the object's own Coulomb friction coefficient (no unit)
COM_OFFSET = "com_offset"  # [x, y] or [x, y, z] m, object frame: the centre of mass off the geometric centre
CONTENTS = "contents_g"  # grams of loose contents in a closed container (part of ``weight_gt``)

# The ranges they are drawn from; benchmarks/physical_properties.py measures how well they are read across them.
FRICTION_RANGE = (0.3, 1.0)  # uniform
COM_RADIUS_SHARE = 0.3  # of the smaller horizontal extent: 0.6 of the way from the centre to the nearest side
CONTENTS_PROBABILITY = 0.5  # of a closed container holding loose contents: a shake has two answers to tell apart
CONTENTS_G = (10.0, 40.0)  # uniform
CONTENTS_SHARE = 0.2  # the contents weigh at most this share of the object, so the container keeps most of it

ORDERS = ("ascending", "descending")  # the order words of a property that has an order (ascending: least first)
# What the hand must do before a property's primitive can measure it (``Property.needs``), as the task planner
# brings it about: hold the object up (grasped and lifted), hold it grasped (lifted or not), or hold it grasped
# standing on the table (one held up is set down first).
HAND_STATES = ("held", "grasped", "standing")
# How much larger than the answer tolerance a comparison margin must be: two values apart by the margin are never
# swapped by two readings each within the tolerance (one high, one low).
MARGIN_OVER_TOLERANCE = 2.0


@dataclass(frozen=True)
class Property:
    """One hidden physical property, registered with ``muble_register_properties``.

    ``name`` is what the measuring ``primitive`` reports (``PrimitiveAction.measures``) and what program steps
    ask for: ``query_<name>``, ``filter_<name>`` (its ``superlatives``, the largest first, or its yes/no
    ``values``) and ``order_<name>`` (its ``orders``). ``truth`` gives an object's ground truth as a query answers
    it; an agent's view carries the measured value under ``measured_key`` (``extra["<name>_measured"]``).
    """

    name: str
    primitive: str  # the primitive that measures it (its ``measures`` is ``name``)
    truth: Callable[[SceneObject], Any]  # the ground truth, as a query answers it; None where the object has none
    description: str = ""
    unit: str = ""  # of a query's answer, in words ("g", "N/m", "mm"; "" for none)
    needs: str = "held"  # HAND_STATES: what the hand does before the primitive (the task planner's sub-goal)
    superlatives: tuple[str, ...] = ()  # (the most, the least), or none
    orders: tuple[str, ...] = ORDERS  # order words, or none (a yes/no property)
    values: tuple[str, ...] = ()  # (yes, no): a yes/no property's filter words, or none
    # The word domain templates draw its superlatives from (``<word_domain>`` parameters); default
    # ``<name>_superlative``.
    word_domain: str | None = None
    # The measured value as an object's view carries it: ``extra[measured_key]`` (default ``<name>_measured``);
    # ``measured_field`` instead names a ``SceneObject`` field (the weight: ``weight``).
    measured_field: str | None = None
    reading: Callable[[Any], Any] = lambda value: value  # a reading as a program compares it
    # The ground truth as the measuring primitive reports it, where that differs from ``truth`` (a centre of mass:
    # [x, y] mm, of which ``truth`` is the distance); None: ``truth``.
    true_reading: Callable[[SceneObject], Any] | None = None
    reading_form: str = "a number"  # in words, for agent writers (docs/agent_api.md)
    answer_form: str = "a number"
    # The accuracy a query's answer is held to, absolute (in ``unit``) and relative (a fraction of the truth): an
    # answer within the larger of the two is right. ``answer_check`` replaces the rule (a yes/no property).
    tolerance: float = 0.0
    tolerance_rel: float = 0.0
    answer_check: Callable[..., bool] | None = None
    # Templates compare two values only when they are apart by ``margin`` (in ``unit``) or ``margin_rel`` (a
    # fraction of the smaller): at least ``MARGIN_OVER_TOLERANCE`` times the tolerance, checked here. None: templates
    # do not compare it (or, for the weight, the generator's ``weight_margin`` decides).
    margin: float | None = None
    margin_rel: float | None = None
    # Sampled by the scene generator (None: the object set gives it, as weight and stiffness): the name
    # ``generator.physical_properties`` and the stream ``scene.<sampled_as>`` use, the ``extra`` key the scene file
    # keeps it under, and the sampler ``(rng, model, weight_g) -> value`` (an ``ObjectModel``; plain JSON values).
    sampled_as: str | None = None
    scene_key: str | None = None
    sampler: Callable[[np.random.Generator, Any, float], Any] | None = None
    # Which objects carry it, ``(spec, model) -> bool`` (an ``ObjectSpec`` and its ``ObjectModel``); None: those the
    # object set declares (``ObjectSet.physical_properties``).
    carried_by: Callable[[Any, Any], bool] | None = None
    # A primitive that measures it again from the state ``primitive`` leaves, with a reading independent of the last
    # (the weight: ``reweigh`` sets the object down, zeroes the sensor and picks it up again, in one call); None: an
    # agent that measures again brings the hand back to ``needs`` as the first time.
    again: str | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)  # anything else a plugin keeps with it

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ValueError(f"property name '{self.name}' must be an identifier (it names program steps)")
        if self.needs not in HAND_STATES:
            raise ValueError(f"property '{self.name}': needs '{self.needs}' is not one of {', '.join(HAND_STATES)}")
        if self.superlatives and len(self.superlatives) != 2 or self.values and len(self.values) != 2:
            raise ValueError(f"property '{self.name}': superlatives and values are pairs (the most, the least; yes, "
                             f"no), got {self.superlatives or self.values}")
        if (self.sampled_as is None) != (self.sampler is None) or (self.sampler is None) != (self.scene_key is None):
            raise ValueError(f"property '{self.name}': a sampled property gives sampled_as, scene_key and sampler "
                             "together; one the object set gives, none of them")
        floor = MARGIN_OVER_TOLERANCE
        if self.margin is not None and self.margin < floor * self.tolerance:
            raise ValueError(f"property '{self.name}': margin {self.margin} {self.unit} must be at least {floor:g} × "
                             f"the tolerance {self.tolerance}, or a reading within tolerance can swap a comparison")
        if self.margin_rel is not None and self.margin_rel < floor * self.tolerance_rel:
            raise ValueError(f"property '{self.name}': margin_rel {self.margin_rel} must be at least {floor:g} × "
                             f"tolerance_rel {self.tolerance_rel}, or a reading within tolerance can swap a "
                             "comparison")

    @property
    def measured_key(self) -> str | None:
        """The ``extra`` key an agent's view carries the measured value under (None: ``measured_field``)."""
        return None if self.measured_field is not None else f"{self.name}_measured"

    @property
    def domain(self) -> str | None:
        """The template word domain of its superlatives (None: it has none)."""
        return (self.word_domain or f"{self.name}_superlative") if self.superlatives else None

    @property
    def compared(self) -> bool:
        """Whether templates compare it by its own margin (``<name>_extreme``, ``<name>_order`` constraints)."""
        return self.margin is not None or self.margin_rel is not None

    @property
    def verb(self) -> str:
        """The measuring primitive, as error messages name it."""
        return self.primitive

    @property
    def stream(self) -> str | None:
        """The random stream its sampler draws from (``muble.core.streams``), or None."""
        return None if self.sampled_as is None else f"scene.{self.sampled_as}"

    def measured(self, obj: SceneObject) -> Any:
        """What an agent's view of ``obj`` holds as measured (None: not measured)."""
        if self.measured_field is not None:
            return getattr(obj, self.measured_field)
        return obj.extra.get(f"{self.name}_measured")

    def reading_truth(self, obj: SceneObject) -> Any:
        """What a perfect measurement of ``obj`` would report (unit and shape of the primitive's reading)."""
        return (self.true_reading or self.truth)(obj)

    def answer_tolerance(self, expected: float) -> float:
        """How far a query's answer may be from the true ``expected``."""
        return max(self.tolerance, self.tolerance_rel * abs(expected))

    def apart(self, high: float, low: float) -> bool:
        """Whether two values (``high`` ≥ ``low``) are far enough apart for a template to compare them."""
        if self.margin_rel is not None:
            return high >= low * (1 + self.margin_rel)
        return high - low >= (self.margin or 0.0)


# The registered records are read through a loader that the plugin machinery installs when ``muble`` is imported
# (``muble.plugins``): the core never imports a plugin.
_loader: Callable[[], Mapping[str, Property]] | None = None


def use_loader(loader: Callable[[], Mapping[str, Property]]) -> None:
    """Where ``registered`` reads the records from (the plugin registry's, installed by ``muble.plugins``)."""
    global _loader
    _loader = loader


def registered() -> Mapping[str, Property]:
    """Every registered hidden property by name: MuBlE's own five in their order (weight, stiffness, friction,
    com_offset, rattles), then those of other packages."""
    if _loader is None:
        raise RuntimeError("no property registry: import muble (which installs the plugin registry) first")
    return _loader()


def named(name: str) -> Property:
    """The registered property ``name``; a ``ValueError`` lists the registered ones."""
    props = registered()
    if name not in props:
        raise ValueError(f"unknown hidden property '{name}'; registered: {', '.join(props)}")
    return props[name]


class Derived(Mapping):
    """A table computed from the registered properties (``build(registered())``), again whenever the registry is
    gathered anew (a plugin installed in a test, a package added): what used to be a module constant per property.
    """

    def __init__(self, build: Callable[[Mapping[str, Property]], Mapping[str, Any]]):
        self._build = build
        self._source: Mapping[str, Property] | None = None
        self._table: Mapping[str, Any] = {}

    def _now(self) -> Mapping[str, Any]:
        props = registered()
        if props is not self._source:
            self._table, self._source = dict(self._build(props)), props
        return self._table

    def __getitem__(self, key: str) -> Any:
        return self._now()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._now())

    def __len__(self) -> int:
        return len(self._now())

    def __reversed__(self) -> Iterator[str]:
        return reversed(list(self._now()))

    def __repr__(self) -> str:
        return f"{dict(self._now())!r}"


# The properties the scene generator draws (``GeneratorConfig.physical_properties``, by ``sampled_as``; which
# objects carry which: ``ObjectSet.physical_properties``) and the scene key each is written under, in
# registration order (the order of their keys in a scene file).
SAMPLED: Mapping[str, Property] = Derived(lambda props: {p.sampled_as: p for p in props.values()
                                                         if p.sampled_as is not None})
PROPERTIES = SAMPLED  # the names, as before (``name in PROPERTIES``, iteration)
SCENE_KEYS: Mapping[str, str] = Derived(lambda props: {p.sampled_as: p.scene_key for p in props.values()
                                                       if p.sampled_as is not None})


def carried(name: str, object_set: Any, spec: Any, model: Any) -> bool:
    """Whether the object ``spec`` (built as ``model``) carries the sampled property ``name``: as the property says
    (``Property.carried_by``), or else as the object set declares (``ObjectSet.physical_properties``)."""
    prop = SAMPLED[name]
    if prop.carried_by is not None:
        return bool(prop.carried_by(spec, model))
    declared = getattr(object_set, "physical_properties", None)
    return declared is not None and name in declared(spec)


def sampled(name: str, rng: np.random.Generator, model: Any, weight_g: float) -> Any:
    """A value of the sampled property ``name`` (its ``sampled_as``, one of ``PROPERTIES``) for the object built as
    ``model`` (an ``ObjectModel``) weighing ``weight_g`` grams, drawn from ``rng`` by the property's sampler."""
    if name not in SAMPLED:
        raise ValueError(f"unknown physical property '{name}'; valid physical property names: "
                         f"{', '.join(SAMPLED)}")
    sampler = SAMPLED[name].sampler
    assert sampler is not None  # a sampled property has one (Property.__post_init__)
    return sampler(rng, model, weight_g)


def friction_of(obj: SceneObject) -> float | None:
    """The object's ground-truth friction coefficient, or None when its scene gives none."""
    value = obj.extra.get(FRICTION)
    return None if value is None else float(value)


def com_offset_mm(obj: SceneObject) -> list[float] | None:
    """The ground truth of a ``balance`` reading: the centre of mass's horizontal offset [x, y] (mm, object frame)
    from the object's origin, or None when its scene gives no centre of mass."""
    value = obj.extra.get(COM_OFFSET)
    return None if value is None else [float(value[0]) * 1000.0, float(value[1]) * 1000.0]


def rattles(obj: SceneObject) -> bool:
    """Whether the object holds loose contents (a ``shake`` reading's ground truth)."""
    return float(obj.extra.get(CONTENTS) or 0.0) > 0.0


def checked(obj: SceneObject) -> dict[str, Any]:
    """The object's properties as ``ObjectModel`` fields (``friction_coefficient``, ``com_offset`` in m,
    ``contents_mass`` in kg), only those its scene gives; a value that is not physical is a
    ``SceneValidationError`` naming the object and the key."""
    return model_fields(obj.extra, obj.weight_gt, obj.id)


def model_fields(extra: Mapping[str, Any], weight_g: float | None, obj_id: int | None = None) -> dict[str, Any]:
    """``checked`` of an object whose ``extra`` and ``weight_gt`` are these (``obj_id`` names it in errors)."""
    out: dict[str, Any] = {}
    if extra.get(FRICTION) is not None:
        mu = _number(obj_id, FRICTION, extra[FRICTION])
        if not mu > 0:
            raise SceneValidationError(f"must be a positive friction coefficient, got {mu}", obj=obj_id,
                                       field=FRICTION)
        out["friction_coefficient"] = mu
    if extra.get(COM_OFFSET) is not None:
        value = extra[COM_OFFSET]
        if not isinstance(value, (list, tuple)) or len(value) not in (2, 3):
            raise SceneValidationError(f"must be [x, y] or [x, y, z] in metres, got {value!r:.60}", obj=obj_id,
                                       field=COM_OFFSET)
        out["com_offset"] = [_number(obj_id, COM_OFFSET, v) for v in value]
    if extra.get(CONTENTS) is not None:
        grams = _number(obj_id, CONTENTS, extra[CONTENTS])
        if grams < 0 or (weight_g is not None and grams >= float(weight_g)):
            raise SceneValidationError(f"must be at least 0 g and less than the weight ({weight_g} g), got "
                                       f"{grams}", obj=obj_id, field=CONTENTS)
        if grams > 0:
            out["contents_mass"] = grams / 1000.0
    return out


def _number(obj_id: int | None, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise SceneValidationError(f"must hold finite numbers, got {value!r:.40}", obj=obj_id, field=key)
    return float(value)
