"""Typed parameters of primitive actions, so that an agent's call is checked before anything runs.

A primitive declares ``params`` as names (any value accepted) or ``Param`` records. The action loop checks
every call against them with ``check_call`` in every world alike: a call that fails the check is the agent's
fault (``Outcome.INVALID_ACTION``), never a crash or a broken scene.

Kinds: ``object`` (the id of an object in the scene), ``part`` (a table part name), ``place`` (either),
``int``, ``number`` (finite, optionally bounded), ``vector`` (``length`` finite numbers, each bounded) and
``any``.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

import numpy as np

from muble.core.errors import PlanningError
from muble.core.types import TABLE_PARTS, canonical_part

KINDS = ("object", "part", "place", "int", "number", "vector", "any")


@dataclass(frozen=True)
class Param:
    """One parameter of a primitive: its name, kind, whether it is required and, for numbers, its bounds."""

    name: str
    kind: str = "any"
    required: bool = False
    low: float | None = None
    high: float | None = None
    length: int | None = None  # for vectors
    doc: str = ""
    # The value an optional parameter takes when a call leaves it out (``argument``); None: the primitive decides
    # (its ``doc`` says how).
    default: Any = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"parameter '{self.name}': unknown kind '{self.kind}'; valid kinds: {', '.join(KINDS)}")

    def describe(self) -> str:
        bounds = ""
        if self.low is not None or self.high is not None:
            bounds = f" in [{self.low if self.low is not None else '-inf'}, " \
                     f"{self.high if self.high is not None else 'inf'}]"
        size = f" of {self.length}" if self.length else ""
        default = f", default {self.default}" if self.default is not None else ""
        return f"{self.name}: {self.kind}{size}{bounds}{'' if self.required else f' (optional{default})'}"


def specs(params: Iterable[str | Param]) -> tuple[Param, ...]:
    """``Param`` records for a primitive's declared ``params`` (a plain name accepts any value)."""
    return tuple(p if isinstance(p, Param) else Param(str(p)) for p in params)


def argument(action: Any, name: str) -> Any:
    """The value of parameter ``name`` in a primitive's call (``PrimitiveAction.arguments``): as given, else its
    declared ``Param.default`` (None where it declares none)."""
    given = action.arguments.get(name)
    if given is not None:
        return given
    return next((p.default for p in specs(type(action).params) if p.name == name), None)


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _bounded(spec: Param, x: float) -> str | None:
    if not math.isfinite(x):
        return f"'{spec.name}' must be finite, got {x}"
    if spec.low is not None and x < spec.low:
        return f"'{spec.name}' must be >= {spec.low}, got {x}"
    if spec.high is not None and x > spec.high:
        return f"'{spec.name}' must be <= {spec.high}, got {x}"
    return None


def check_value(spec: Param, value: Any, object_ids: Sequence[int]) -> str | None:
    """Why ``value`` is not a valid ``spec`` argument, or None."""
    kind = spec.kind
    if kind == "any":
        return None
    if kind in ("object", "place") and _is_int(value):
        if int(value) not in object_ids:
            return f"'{spec.name}' names object {value}, which is not in the scene (ids: {list(object_ids)})"
        return None
    if kind in ("part", "place") and isinstance(value, str):
        try:
            canonical_part(value)
        except PlanningError:
            return f"'{spec.name}' names table part '{value}'; valid parts: {', '.join(TABLE_PARTS)}"
        return None
    if kind == "int":
        return _bounded(spec, float(value)) if _is_int(value) else \
            f"'{spec.name}' must be an integer, got {type(value).__name__} {value!r:.40}"
    if kind == "number":
        return _bounded(spec, float(value)) if _is_number(value) else \
            f"'{spec.name}' must be a number, got {type(value).__name__} {value!r:.40}"
    if kind == "vector":
        if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
            return f"'{spec.name}' must be a list of {spec.length or 'some'} numbers, got {type(value).__name__}"
        items = list(np.asarray(value, dtype=object).reshape(-1)) if isinstance(value, np.ndarray) else list(value)
        if spec.length is not None and len(items) != spec.length:
            return f"'{spec.name}' must have {spec.length} values, got {len(items)}"
        for x in items:
            if not _is_number(x):
                return f"'{spec.name}' must hold numbers only, got {type(x).__name__} {x!r:.40}"
            problem = _bounded(spec, float(x))
            if problem:
                return problem
        return None
    expected = {"object": "an object id (integer)", "part": "a table part name",
                "place": "an object id (integer) or a table part name"}[kind]
    return f"'{spec.name}' must be {expected}, got {type(value).__name__} {value!r:.40}"


def check_call(name: str, declared: Iterable[str | Param], params: Any, object_ids: Sequence[int]) -> str | None:
    """Why a call of primitive ``name`` with ``params`` is invalid in a scene with ``object_ids``, or None."""
    if not isinstance(params, dict):
        return f"{name}: parameters must be a mapping of name to value, got {type(params).__name__}"
    declared = specs(declared)
    by_name = {p.name: p for p in declared}
    accepts = "; it accepts: " + (", ".join(p.describe() for p in declared) or "no parameters")
    unknown = sorted(str(k) for k in params if k not in by_name)
    if unknown:
        return f"{name}: unknown parameter(s) {unknown}{accepts}"
    missing = [p.name for p in declared if p.required and p.name not in params]
    if missing:
        return f"{name}: missing parameter(s) {missing}{accepts}"
    for key, value in params.items():
        problem = check_value(by_name[key], value, object_ids)
        if problem:
            return f"{name}: {problem}"
    return None
