"""How scene objects meet MuJoCo, the conventions every part shares: object names in the compiled model, and the
compliant contact law that turns an object's stiffness (N/m) into MuJoCo's ``solref``/``solimp``.

Object ``i`` is the body ``obj{i}``; every name that belongs to it starts with ``obj{i}`` followed by ``_`` or the
end (see ``muble.sim.object_mjcf`` for the full convention and docs/environment.md, "Stiffness", for the law).
Renderers map segmentation back to scene ids and object sets report the stiffness the law realises through these
functions.
"""
from __future__ import annotations

import math
import re

# Constant impedance: stiffness must not depend on penetration depth, or squeeze would see a non-linear spring.
CONTACT_IMPEDANCE = 0.95
# Weight of the object's solimp when MuJoCo mixes it with the other geom's (robosuite's fingers and table use a
# depth-dependent 0.9-0.95 impedance): 1e6 : 1 leaves the object's constant impedance within 5e-8.
CONTACT_SOLMIX = 1.0e6
# Time constant floor of 2 physics steps (2 ms each, robosuite's default), MuJoCo's stability rule of thumb.
MIN_TIME_CONSTANT = 0.004
MAX_ACCEL_STIFFNESS = 1.0 / MIN_TIME_CONSTANT**2
# Geom priority of an object with its own friction coefficient: MuJoCo takes the friction of the geom with the
# higher priority (robosuite's table and fingers have 0), so the object's coefficient decides its contacts.
FRICTION_PRIORITY = 1
# contype and conaffinity of a closed container's inner walls and of the loose contents inside them: they meet
# each other only (the world's geoms use bit 1), so the contents rattle between the walls inside the container's
# solid collision parts. Nothing outside the container ever touches them, so planning leaves them out.
CONTENTS_COLLISION_CLASS = 2
# The least cosine between a jaw contact's normal and that jaw's closing direction for the contact to set how far
# the jaw has advanced into the object (60 degrees): the jaw contact law presses with the penetration of each jaw's
# deepest such point (``muble.sim.jaw_contact``), and squeezing reads the jaw's travel there.
JAW_SQUARE = 0.5

_NAME_RE = re.compile(r"^obj(\d+)(?:_|$)")


def object_body_name(object_id: int) -> str:
    """The MuJoCo body name of scene object ``object_id`` (``obj{id}``)."""
    return f"obj{object_id}"


def object_id_from_name(name: str | None) -> int | None:
    """The object id encoded in an MJCF name (``obj3_col2`` → 3), or ``None`` for anything else."""
    if not name:
        return None
    match = _NAME_RE.match(name)
    return int(match.group(1)) if match else None


def contact_solref(stiffness: float, damping_ratio: float, mass: float) -> tuple[tuple[float, float], tuple]:
    """Direct-mode ``solref`` and constant ``solimp`` that make one contact point of the object with an immovable
    surface a spring of ``stiffness`` (the base law; jaw contacts are rescaled at run time, see module doc).

    ``stiffness`` in N/m, ``mass`` in kg (the object's), ``damping_ratio`` 1 = critically damped.
    """
    d = CONTACT_IMPEDANCE
    k = stiffness * (1.0 - d) / mass
    k = min(k, MAX_ACCEL_STIFFNESS)
    b = 2.0 * damping_ratio * math.sqrt(k)
    solimp = (d, d, 0.001, 0.5, 2.0)
    return (-k, -b), solimp


def realised_stiffness(stiffness: float, mass: float) -> float:
    """The stiffness (N/m) ``contact_solref`` actually realises for an object of ``mass`` (after the cap)."""
    (k, _), _ = contact_solref(stiffness, 1.0, mass)
    return stiffness_of_solref(-k, mass)


def realised_damping(stiffness: float, damping_ratio: float, mass: float) -> float:
    """The contact damping (N·s/m) that goes with ``contact_solref`` for an object of ``mass``."""
    (_, b), _ = contact_solref(stiffness, damping_ratio, mass)
    return stiffness_of_solref(-b, mass)


def stiffness_of_solref(k: float, mass: float) -> float:
    """The point stiffness (N/m) of direct-mode ``k`` (= -solref[0]) against an immovable surface: at rest
    ``f/r = k / ((1-d)·A)`` with ``A = 1/mass``; the same map turns ``b`` into a damping in N·s/m."""
    return k * mass / (1.0 - CONTACT_IMPEDANCE)
