"""Value ranges declared in config schemas and checked after composition.

OmegaConf checks types but not ranges, so a schema field that must be positive declares it with ``bounded``::

    @dataclass
    class PlannerConfig:
        time_limit: float = bounded(2.0, gt=0)  # s

``check_ranges(cfg)`` walks a composed config, finds every structured node's dataclass and reports all values
out of range in one ``ConfigError`` that names each key, its value and the allowed range.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from muble.core.errors import ConfigError

RANGE_KEY = "muble_range"


@dataclass(frozen=True)
class Range:
    """Bounds of a number (or of every number in a list when ``each``)."""

    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    each: bool = False

    def contains(self, value: Any) -> bool:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
            return False
        return not ((self.gt is not None and value <= self.gt) or (self.ge is not None and value < self.ge)
                    or (self.lt is not None and value >= self.lt) or (self.le is not None and value > self.le))

    def describe(self) -> str:
        parts = [f"{op} {_number(bound)}" for op, bound in
                 ((">", self.gt), (">=", self.ge), ("<", self.lt), ("<=", self.le)) if bound is not None]
        return ("each " if self.each else "") + " and ".join(parts)


def _number(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else str(x)


def bounded(default: Any = dataclasses.MISSING, *, gt: float | None = None, ge: float | None = None,
            lt: float | None = None, le: float | None = None, each: bool = False,
            default_factory: Any = dataclasses.MISSING) -> Any:
    """A dataclass field whose value (or, with ``each``, every item of its list) must lie in the given range."""
    metadata = {RANGE_KEY: Range(gt, ge, lt, le, each)}
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def range_violations(cfg: Any, path: str = "") -> list[str]:
    """``"key = value (must be …)"`` for every value of ``cfg`` outside its schema's declared range."""
    from omegaconf import DictConfig, OmegaConf

    problems: list[str] = []
    if not isinstance(cfg, DictConfig):
        return problems
    schema = OmegaConf.get_type(cfg)
    declared = {f.name: f.metadata[RANGE_KEY] for f in dataclasses.fields(schema)
                if RANGE_KEY in f.metadata} if dataclasses.is_dataclass(schema) else {}
    for key in cfg.keys():
        key = str(key)
        if key == "hydra" and not path:
            continue
        full = f"{path}.{key}" if path else key
        bounds = declared.get(key)
        if OmegaConf.is_missing(cfg, key) or (bounds is None and OmegaConf.is_interpolation(cfg, key)):
            continue  # a missing value is reported where it is read; unbounded interpolations stay unresolved
        value = cfg[key]
        if isinstance(value, DictConfig):
            problems.extend(range_violations(value, full))
            continue
        if bounds is None or value is None:
            continue
        values = list(value) if bounds.each and OmegaConf.is_list(value) else [value]
        bad = [v for v in values if not bounds.contains(v)]
        if bad:
            shown = list(value) if bounds.each and OmegaConf.is_list(value) else value
            problems.append(f"{full}={shown} (must be {bounds.describe()})")
    return problems


def check_ranges(cfg: Any) -> None:
    """Raise one ``ConfigError`` naming every out-of-range value of a composed config."""
    problems = range_violations(cfg)
    if problems:
        raise ConfigError("value out of range: " + "; ".join(problems) + "; change "
                          + ("it" if len(problems) == 1 else "them") + " on the command line or in the config")
