"""MuBlE's own five hidden properties, one ``Property`` record each, registered beside the primitives that measure
them (``weigh``, ``squeeze``, ``push``, ``balance``, ``shake``).

Their order is the order every table derived from them keeps (program steps, the agent view's measured keys, the
scene generator's streams and a scene file's keys), so it stays as it is; a package's properties come after them.
The three the scene generator draws (friction, centre of mass, loose contents) carry their samplers here; weight
and stiffness are given by the object set. The answer tolerances are what the measuring primitives are held to
(docs/physical_properties.md); each comparison margin is at least twice its tolerance, which ``Property`` checks.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from muble import Property, SceneObject
from muble.core import physical_properties as physical
from muble.programs.program import (COM_SUPERLATIVES, FRICTION_SUPERLATIVES, RATTLE_VALUES, STIFFNESS_SUPERLATIVES,
                                    WEIGHT_SUPERLATIVES)

from muble_plugins.common.success import rattles_match

WEIGHT_TOLERANCE_G = 2.0  # absolute slack on an answered weight …
WEIGHT_TOLERANCE_REL = 0.02  # … or this fraction of it, whichever is larger
STIFFNESS_TOLERANCE_REL = 0.05  # an answered stiffness within this fraction of the true one
FRICTION_TOLERANCE_REL = 0.10  # an answered friction coefficient within this fraction of the true one (push)
COM_TOLERANCE_MM = 5.0  # an answered centre-of-mass offset (mm from the centre) within this of the true one
STIFFNESS_MARGIN = 0.25  # stiffnesses a template compares differ by at least this fraction of the smaller
FRICTION_MARGIN = 0.25  # friction coefficients likewise (2.5 times the tolerance)
COM_MARGIN_MM = 10.0  # centre-of-mass offsets (mm from the centre) differ by at least this


def friction_sample(rng: np.random.Generator, model: Any, weight_g: float) -> float:
    """A coefficient uniform in ``FRICTION_RANGE``, 3 decimals (one draw)."""
    return round(float(rng.uniform(*physical.FRICTION_RANGE)), 3)


def com_offset_sample(rng: np.random.Generator, model: Any, weight_g: float) -> list[float]:
    """[x, y] m, uniform over the disc of radius ``COM_RADIUS_SHARE`` of the smaller horizontal extent about the
    base centre, 4 decimals (two draws: the angle, then the radius)."""
    radius = physical.COM_RADIUS_SHARE * float(min(model.extents[:2]))
    angle, r = float(rng.uniform(0.0, 2.0 * math.pi)), radius * math.sqrt(float(rng.uniform()))
    return [round(r * math.cos(angle), 4) + 0.0, round(r * math.sin(angle), 4) + 0.0]  # + 0.0: no "-0.0"


def contents_sample(rng: np.random.Generator, model: Any, weight_g: float) -> float:
    """Grams, 0.1 g: with ``CONTENTS_PROBABILITY`` uniform in ``CONTENTS_G`` and at most ``CONTENTS_SHARE`` of the
    weight, else 0.0, a container known to be empty (one draw, two with contents). Only a closed container
    (``ObjectModel.closed``) holds contents: another is a ``ValueError``."""
    if not model.closed:
        raise ValueError(f"a {model.spec.category} is no closed container: it cannot hold loose contents")
    if float(rng.uniform()) >= physical.CONTENTS_PROBABILITY:
        return 0.0
    return round(min(float(rng.uniform(*physical.CONTENTS_G)), physical.CONTENTS_SHARE * float(weight_g)), 1)


def offset_mm(value: Any) -> float | None:
    """The distance (mm) of a centre-of-mass offset [x, y] (mm) from the centre, as a query answers it."""
    return None if value is None else round(math.hypot(float(value[0]), float(value[1])), 2)


def _rattles_truth(obj: SceneObject) -> bool | None:
    return None if obj.extra.get(physical.CONTENTS) is None else physical.rattles(obj)


WEIGHT = Property(
    "weight", "weigh", lambda o: o.weight_gt, "the object's weight", unit="g", needs="held",
    superlatives=WEIGHT_SUPERLATIVES, measured_field="weight", again="reweigh",
    tolerance=WEIGHT_TOLERANCE_G, tolerance_rel=WEIGHT_TOLERANCE_REL)
STIFFNESS = Property(
    "stiffness", "squeeze", lambda o: o.stiffness, "how hard the object is to squeeze (contact stiffness)",
    unit="N/m", needs="grasped", superlatives=STIFFNESS_SUPERLATIVES,
    tolerance_rel=STIFFNESS_TOLERANCE_REL, margin_rel=STIFFNESS_MARGIN)
FRICTION = Property(
    "friction", "push", physical.friction_of, "how slippery the object is (its friction coefficient)",
    needs="standing", superlatives=FRICTION_SUPERLATIVES, tolerance_rel=FRICTION_TOLERANCE_REL,
    margin_rel=FRICTION_MARGIN, sampled_as="friction", scene_key=physical.FRICTION, sampler=friction_sample)
COM = Property(
    "com_offset", "balance", lambda o: offset_mm(physical.com_offset_mm(o)),
    "how far the object's centre of mass sits off its centre", unit="mm", needs="held",
    superlatives=COM_SUPERLATIVES, word_domain="com_superlative", reading=offset_mm,
    true_reading=physical.com_offset_mm, reading_form="[x, y]: the offset in the object's frame",
    answer_form="a number: the offset's distance from the centre, sqrt(x² + y²) of the reading",
    tolerance=COM_TOLERANCE_MM, margin=COM_MARGIN_MM, sampled_as="com_offset", scene_key=physical.COM_OFFSET,
    sampler=com_offset_sample)
RATTLES = Property(
    "rattles", "shake", _rattles_truth, "whether loose contents rattle inside a closed container", needs="held",
    values=RATTLE_VALUES, orders=(), reading_form="true or false",
    answer_form='true or false (or the words "yes" and "no")', answer_check=rattles_match,
    sampled_as="contents", scene_key=physical.CONTENTS, sampler=contents_sample)

BUILTIN = (WEIGHT, STIFFNESS, FRICTION, COM, RATTLES)
