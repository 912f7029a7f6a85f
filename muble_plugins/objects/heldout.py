"""What a catalogue's sampling may draw under the held-out options of a generalisation split.

``exclude_models``/``only_models`` name models of the catalogue's ``variants``; ``exclude_finishes``/
``only_finishes`` name colour-material combinations as ``"colour material"`` ("red plastic"); ``property_range``
picks the part of every weight and stiffness range that is sampled. Unfiltered, every table is the catalogue's
own and every draw the one it always made, so scenes generated at the defaults do not change.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from muble.core.errors import ConfigError, unknown_name

from muble_plugins.objects.category import Category, Finish

# Which part of each weight and stiffness range is sampled (``property_range``): "inner" keeps the middle
# ``inner_fraction`` of every range, "outer" the two tails beside it, so that a test split's properties lie where
# no training object's did, yet inside the ranges the physics was validated on.
PROPERTY_RANGES = ("all", "inner", "outer")


def finish_name(colour: str, material: str) -> str:
    """How ``exclude_finishes``/``only_finishes`` name a colour-material combination: ``"red plastic"``."""
    return f"{colour} {material}"


def sample_range_part(rng: np.random.Generator, low: float, high: float, part: str, inner_fraction: float) -> float:
    """A uniform sample of [``low``, ``high``] (``part="all"``: one ``rng.uniform`` draw, as always), of its middle
    ``inner_fraction`` (``"inner"``) or of the two tails beside that middle (``"outer"``).

    The tails are equally wide, so one draw over their joint length picks each with probability 1/2; the upper
    tail is mapped from its top down, so "outer" lies in [low, inner low) and (inner high, high] and "inner" in
    [inner low, inner high): the two never share a value.
    """
    if part == "all":
        return float(rng.uniform(low, high))
    tail = (high - low) * (1.0 - inner_fraction) / 2.0
    if part == "inner":
        return float(rng.uniform(low + tail, high - tail))
    u = float(rng.uniform(0.0, 2.0 * tail))
    return low + u if u < tail else high - (u - tail)


def check_property_range(part: str) -> None:
    """``ConfigError`` for a ``property_range`` other than all/inner/outer (``inner_fraction``'s bounds are its
    config field's: ``ObjectSetConfig``)."""
    if part not in PROPERTY_RANGES:
        raise ConfigError(unknown_name("property_range", part, PROPERTY_RANGES))


@dataclass(frozen=True)
class SampledCategory:
    """What sampling draws from for one category once the filters have applied: its models and its finishes, each
    finish keeping only its allowed colours. Unfiltered, these are the category's own tuples, so the draws (an
    index into each) are those of the catalogue itself."""

    models: tuple[str, ...]
    finishes: tuple[Finish, ...]


def sampled_categories(catalogue: dict[str, Category], set_name: str, exclude_models: list[str],
                       only_models: list[str], exclude_finishes: list[str], only_finishes: list[str]
                       ) -> dict[str, SampledCategory]:
    """Per category of ``catalogue``, what is left to sample; a category left without a model or without a
    finish is absent. An ``only_*`` list keeps nothing else, an ``exclude_*`` list removes what it names (both
    may be given). A name that is no model or finish of the set is a ``ConfigError`` listing the valid ones."""
    models = [m for cat in catalogue.values() for m in cat.variants]
    finishes = sorted({finish_name(c, f.material) for cat in catalogue.values() for f in cat.finishes
                       for c in f.colours})
    for name in [*exclude_models, *only_models]:
        if name not in models:
            raise ConfigError(unknown_name(f"{set_name} model", name, models))
    for name in [*exclude_finishes, *only_finishes]:
        if name not in finishes:
            raise ConfigError(unknown_name(f"{set_name} finish", name, finishes))

    def allowed(name: str, excluded: list[str], only: list[str]) -> bool:
        return name not in excluded and (not only or name in only)

    sampled = {}
    for cat in catalogue.values():
        kept_models = tuple(m for m in cat.variants if allowed(m, exclude_models, only_models))
        kept_finishes = []
        for finish in cat.finishes:
            colours = tuple(c for c in finish.colours
                            if allowed(finish_name(c, finish.material), exclude_finishes, only_finishes))
            if colours:
                kept_finishes.append(finish if colours == finish.colours else
                                     dataclasses.replace(finish, colours=colours))
        if kept_models and kept_finishes:
            sampled[cat.name] = SampledCategory(kept_models, tuple(kept_finishes))
    return sampled
