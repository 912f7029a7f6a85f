"""Value ranges declared in config schemas and checked after composition.

OmegaConf checks types but not ranges, so a schema field that must be positive declares it with ``bounded``::

    @dataclass
    class PlannerConfig:
        time_limit: float = bounded(2.0, gt=0)  # s

``check_ranges(cfg)`` walks a composed config, finds every structured node's dataclass and reports all values
out of range in one ``ConfigError`` that names each key, its value and the allowed range. ``configured(schema,
config, overrides, owner=...)`` builds one schema instance the same way (type-checked, range-checked, an unknown
key listing the valid ones): the schema is the only place that declares an option's default and its bounds.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping, TypeVar, cast

from muble.core.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from omegaconf import DictConfig

RANGE_KEY = "muble_range"
T = TypeVar("T")


@dataclass(frozen=True)
class Range:
    """Bounds of a number (or of every number in a list when ``each``); ``hint`` says what the number is (a unit,
    what null means) in the message of a value out of range."""

    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    each: bool = False
    hint: str = ""

    def contains(self, value: Any) -> bool:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
            return False
        return not ((self.gt is not None and value <= self.gt) or (self.ge is not None and value < self.ge)
                    or (self.lt is not None and value >= self.lt) or (self.le is not None and value > self.le))

    def describe(self) -> str:
        if self.ge is not None and self.le is not None and self.gt is None and self.lt is None:
            text = f"{_number(self.ge)}..{_number(self.le)}"
        else:
            text = " and ".join(f"{op} {_number(bound)}" for op, bound in
                                ((">", self.gt), (">=", self.ge), ("<", self.lt), ("<=", self.le)) if bound is not None)
        return ("each " if self.each else "") + text + (f" ({self.hint})" if self.hint else "")


def _number(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else str(x)


def bounded(default: Any = dataclasses.MISSING, *, gt: float | None = None, ge: float | None = None,
            lt: float | None = None, le: float | None = None, each: bool = False, hint: str = "",
            default_factory: Any = dataclasses.MISSING) -> Any:
    """A dataclass field whose value (or, with ``each``, every item of its list) must lie in the given range; a
    None value of an optional field is always accepted."""
    metadata = {RANGE_KEY: Range(gt, ge, lt, le, each, hint)}
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def range_violations(cfg: Any, path: str = "") -> list[str]:
    """``"key must be …, got value"`` for every value of ``cfg`` outside its schema's declared range."""
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
            problems.append(f"{full} must be {bounds.describe()}, got {shown}")
    return problems


def check_ranges(cfg: Any) -> None:
    """Raise one ``ConfigError`` naming every out-of-range value of a composed config."""
    problems = range_violations(cfg)
    if problems:
        raise ConfigError("value out of range: " + "; ".join(problems) + "; change "
                          + ("it" if len(problems) == 1 else "them") + " on the command line or in the config")


def checked_node(schema: type, *layers: Any, owner: str) -> "DictConfig":
    """The structured config of the dataclass ``schema`` with ``layers`` merged on in order (each an instance of
    ``schema`` or a mapping of its fields; None is skipped), its types and ranges checked. A key the schema lacks,
    a value of the wrong type or out of range is a ``ConfigError`` naming ``owner`` (``renderer 'mujoco'``)."""
    from omegaconf import DictConfig, OmegaConf
    from omegaconf.errors import OmegaConfBaseException

    valid = [f.name for f in dataclasses.fields(schema)]
    merged_layers = []
    for layer in layers:
        if layer is None:
            continue
        if isinstance(layer, DictConfig):
            layer = OmegaConf.to_container(layer, resolve=True)
        if isinstance(layer, Mapping):
            unknown = sorted(str(k) for k in set(layer) - set(valid))
            if unknown:
                raise ConfigError(f"{owner} has no option(s) {unknown}; valid options: {', '.join(valid) or '(none)'}")
            layer = dict(layer)
        elif not isinstance(layer, schema):
            raise ConfigError(f"{owner} takes a {schema.__name__} or a mapping of its options, "
                              f"got {type(layer).__name__}")
        merged_layers.append(layer)
    try:
        merged = OmegaConf.merge(OmegaConf.structured(schema), *merged_layers)
    except OmegaConfBaseException as e:
        key = getattr(e, "full_key", None)
        what = str(getattr(e, "msg", e)).strip().splitlines()[0]
        raise ConfigError(f"{owner}: " + (f"option {key}: " if key else "") + what) from e
    problems = range_violations(merged)
    if problems:
        raise ConfigError(f"{owner}: value out of range: {'; '.join(problems)}")
    return cast("DictConfig", merged)  # a dataclass schema merges to a DictConfig


def configured(schema: type[T], config: T | Mapping[str, Any] | None = None,
               overrides: Mapping[str, Any] | None = None, *, owner: str) -> T:
    """An instance of the dataclass ``schema``: its defaults, then ``config`` (an instance or a mapping of its
    fields), then ``overrides``, checked as ``checked_node`` checks them."""
    from omegaconf import OmegaConf

    return cast(T, OmegaConf.to_object(checked_node(schema, config, overrides, owner=owner)))
