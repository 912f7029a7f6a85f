"""Describing scene objects in words, the SHOP-VRB2 way: the shortest attribute descriptions that denote exactly one
object (or exactly a set of objects), and the noun phrase for a description.

A description is a tuple of ``(attribute, value)`` pairs over ``DESCRIPTION_ATTRIBUTES``. Every subset of those
attributes groups the scene's objects by their values; a group of one object gives a unique description, a larger
group a plural one. Only the shortest descriptions of each object (or set) are kept, plus ``extra_steps`` longer
ones, so an instruction never says more than needed and never denotes anything but its intended objects. Task
plugins use ``SceneIndex`` and ``describe`` to word their instructions (docs/plugins.md).
"""
from __future__ import annotations

from itertools import combinations
from operator import itemgetter

from muble.core.scene import SceneGraph

# Attributes a description may use, in the order the words appear ("small red ceramic cylindrical mug").
DESCRIPTION_ATTRIBUTES = ("size", "colour", "material", "shape", "name")
ATTRIBUTE_STEP = {
    "size": "filter_size",
    "colour": "filter_colour",
    "material": "filter_material",
    "shape": "filter_shape",
    "name": "filter_name",
}
# Shape values as stored in scenes -> the adjective used in text.
SHAPE_ADJECTIVE = {
    "flat": "flat",
    "hemisphere": "hemispherical",
    "cuboid": "cuboid",
    "cylindrical": "cylindrical",
    "irregularly shaped": "irregularly shaped",
}
IRREGULAR_PLURALS = {"knife": "knives", "glass": "glasses", "wine glass": "wine glasses", "food box": "food boxes",
                     "dish": "dishes", "mouse": "mice"}
GENERIC_NOUN = "object"


def plural(noun: str) -> str:
    """The plural of an object name as instructions word it ("mug" -> "mugs", "glass" -> "glasses")."""
    if noun in IRREGULAR_PLURALS:
        return IRREGULAR_PLURALS[noun]
    if noun.endswith(("s", "x", "ch", "sh")):
        return noun + "es"
    return noun + "s"


def describe(description: tuple[tuple[str, str], ...], *, many: bool = False) -> str:
    """The noun phrase of a description: adjectives in ``DESCRIPTION_ATTRIBUTES`` order, then the noun."""
    values = dict(description)
    words = []
    for attr in DESCRIPTION_ATTRIBUTES[:-1]:
        if attr in values:
            words.append(SHAPE_ADJECTIVE.get(values[attr], values[attr]) if attr == "shape" else values[attr])
    noun = values.get("name", GENERIC_NOUN)
    words.append(plural(noun) if many else noun)
    return " ".join(words)


Description = tuple[tuple[str, str], ...]
"""A description of objects: (attribute, value) pairs, e.g. ``(("colour", "red"), ("name", "mug"))``; ``describe``
words it as a noun phrase."""

_SUBSETS = [c for k in range(len(DESCRIPTION_ATTRIBUTES) + 1) for c in combinations(DESCRIPTION_ATTRIBUTES, k)]


def _values_of(attrs: tuple[str, ...]):
    """A function from an object's values (in ``DESCRIPTION_ATTRIBUTES`` order) to the tuple of its ``attrs`` values."""
    at = [DESCRIPTION_ATTRIBUTES.index(a) for a in attrs]
    if len(at) > 1:
        return itemgetter(*at)
    return (lambda values: (values[at[0]],)) if at else (lambda values: ())


# Each subset with its getter: a scene's index is built from all 32 for every scene generated.
_SUBSET_VALUES = [(attrs, _values_of(attrs)) for attrs in _SUBSETS]


class SceneIndex:
    """Descriptions of one scene.

    ``unique[obj_id]``: descriptions denoting exactly that object (shortest first).
    ``groups[ids]``: descriptions denoting exactly the object set ``ids`` (a sorted tuple of two or more ids).
    """

    def __init__(self, scene: SceneGraph, extra_steps: int = 0):
        self.scene = scene
        self.objects = {o.id: o for o in scene.objects}
        rows = [(o.id, tuple(getattr(o, a) for a in DESCRIPTION_ATTRIBUTES)) for o in scene.objects]
        unique: dict[int, list[tuple[int, Description]]] = {}
        groups: dict[tuple[int, ...], list[tuple[int, Description]]] = {}
        for attrs, values_of in _SUBSET_VALUES:
            buckets: dict[tuple[str, ...], list[int]] = {}
            for i, values in rows:
                buckets.setdefault(values_of(values), []).append(i)
            for key, members in buckets.items():
                desc = tuple(zip(attrs, key))
                if len(members) == 1:
                    unique.setdefault(members[0], []).append((len(attrs), desc))
                else:
                    groups.setdefault(tuple(sorted(members)), []).append((len(attrs), desc))
        self.unique = {i: _shortest(ds, extra_steps) for i, ds in unique.items()}
        self.groups = {g: _shortest(ds, extra_steps) for g, ds in groups.items()}

    def denotes(self, description: Description) -> list[int]:
        """The ids of every object matching ``description`` (used to verify that nothing is ambiguous)."""
        return [i for i, o in self.objects.items() if all(getattr(o, a) == v for a, v in description)]


def _shortest(found: list[tuple[int, Description]], extra_steps: int) -> list[Description]:
    # Subsets come in order of size, so the first entry has the shortest length.
    limit = found[0][0] + extra_steps
    return [d for n, d in found if n <= limit]
