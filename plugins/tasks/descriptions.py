"""Short object descriptions of a scene and the exact object sets they denote.

A description is a tuple of ``(attribute, value)`` pairs. Every subset of the five description attributes
groups the scene's objects by their values; a group of one object gives a unique description, a larger group a
plural one. Only the shortest descriptions of each object (or set) are kept, plus ``extra_steps`` longer ones,
so an instruction never says more than needed and never denotes anything but its intended objects.
"""
from __future__ import annotations

from itertools import combinations

from muble import SceneGraph

from muble_plugins.tasks.vocabulary import DESCRIPTION_ATTRIBUTES

Description = tuple[tuple[str, str], ...]

_SUBSETS = [c for k in range(len(DESCRIPTION_ATTRIBUTES) + 1) for c in combinations(DESCRIPTION_ATTRIBUTES, k)]


class SceneIndex:
    """Descriptions of one scene.

    ``unique[obj_id]``: descriptions denoting exactly that object (shortest first).
    ``groups[ids]``: descriptions denoting exactly the object set ``ids`` (a sorted tuple of two or more ids).
    """

    def __init__(self, scene: SceneGraph, extra_steps: int = 0):
        self.scene = scene
        self.objects = {o.id: o for o in scene.objects}
        ids = [o.id for o in scene.objects]
        values = {o.id: {a: getattr(o, a) for a in DESCRIPTION_ATTRIBUTES} for o in scene.objects}
        unique: dict[int, list[tuple[int, Description]]] = {}
        groups: dict[tuple[int, ...], list[tuple[int, Description]]] = {}
        for attrs in _SUBSETS:
            buckets: dict[tuple[str, ...], list[int]] = {}
            for i in ids:
                buckets.setdefault(tuple(values[i][a] for a in attrs), []).append(i)
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
