"""Named random streams: every purpose that draws random numbers has a stream of its own, derived here.

A stream is ``numpy.random.SeedSequence(seed, spawn_key=(purpose key, *key))``: the run's seed is the entropy,
the purpose's key (the first four bytes of the sha256 of its name, as an unsigned integer) is the first element of
the spawn key and the purpose's own numbers (a scene index, a scene sample …) follow. Two purposes therefore
never share a stream, whatever numbers they pass: their spawn keys differ in their first element. Adding a purpose,
or more draws to one, leaves every other purpose's draws as they were, so a new hidden property drawn from a
stream of its own does not change a file that was frozen before it existed.

Purposes are declared with ``declare`` (at import time of the module that draws from them); ``PURPOSES`` lists
them with what each one draws, and a name whose key collides with another's is refused when declared. A plugin
declares its own purposes the same way.
"""
from __future__ import annotations

import hashlib

import numpy as np

PURPOSES: dict[str, str] = {}  # name -> what it draws
_KEYS: dict[int, str] = {}


def purpose_key(name: str) -> int:
    """The fixed 32-bit key of a purpose's name (the first element of its streams' spawn keys)."""
    return int.from_bytes(hashlib.sha256(name.encode()).digest()[:4], "big")


def declare(name: str, about: str) -> str:
    """Declare a purpose (idempotent); returns its name. Raises ``ValueError`` when another name has its key."""
    key = purpose_key(name)
    other = _KEYS.get(key)
    if other is not None and other != name:
        raise ValueError(f"random stream purpose '{name}' has the key of '{other}' ({key}); choose another name")
    _KEYS[key] = name
    PURPOSES[name] = about
    return name


def seed_sequence(purpose: str, seed: int, *key: int) -> np.random.SeedSequence:
    """The ``SeedSequence`` of ``purpose``'s stream for ``seed`` and its own numbers ``key``."""
    if purpose not in PURPOSES:
        raise KeyError(f"random stream purpose '{purpose}' is not declared (muble.core.streams.declare); "
                       f"declared: {', '.join(sorted(PURPOSES))}")
    ints = [int(k) for k in key]
    if any(k < 0 for k in ints) or int(seed) < 0:
        raise ValueError(f"stream '{purpose}': seed and key must be non-negative integers, got {seed}, {ints}")
    return np.random.SeedSequence(int(seed), spawn_key=(purpose_key(purpose), *ints))


def stream(purpose: str, seed: int, *key: int) -> np.random.Generator:
    """A generator (PCG64) on ``purpose``'s stream for ``seed`` and ``key``."""
    return np.random.default_rng(seed_sequence(purpose, seed, *key))


# The purposes of scene and episode generation (muble.generation, muble.episode); each key is listed with it.
SCENE_OBJECTS = declare("scene.objects", "a scene sample's object count, models, finishes, sizes, weights and "
                        "stiffnesses (index, sample)")
SCENE_LAYOUT = declare("scene.layout", "a scene sample's object placements on the table (index, sample)")
CAMERA_JITTER = declare("scene.camera_jitter", "a scene's camera offset and turn (index)")
LAMP_JITTER = declare("scene.lamp_jitter", "a scene's lamp offsets and energies (index)")
# The hidden physical properties (muble.core.physical_properties), one stream each ("scene.<property>"), drawn
# per layout tried, per object that carries the property, in scene order.
PROPERTY_STREAMS = {name: declare(f"scene.{name}", f"a scene sample's {what} (index, sample)") for name, what in (
    ("friction", "friction coefficients of its objects"), ("com_offset", "centre-of-mass offsets of its objects"),
    ("contents", "loose contents of its closed containers"))}
SENSOR_WRIST_NOISE = declare("sensor.wrist_noise", "the wrist force/torque sensor's drifting bias and white noise "
                             "in an episode (index; muble.sim.sensor_noise)")
DISTURBANCE_MIX = declare("episode.disturbance_mix", "which of the enabled disturbances act in an episode (index)")
INSTRUCTION = declare("episode.instruction", "the instruction a template draws for a scene (index)")
TEMPLATE_MIX = declare("split.template_mix", "the order of templates within a block of a split (block)")
COUNT_MIX = declare("split.count_mix", "the order of object counts within a block of a split (block)")


def disturbance_stream(kind: str, seed: int, index: int) -> np.random.Generator:
    """The generator of the disturbance registered as ``kind`` for episode ``index`` of a run seeded ``seed``: its
    own purpose, ``episode.disturbance.<kind>``, declared on first use (muble.core.interfaces.Disturbance)."""
    name = f"episode.disturbance.{kind}"
    if name not in PURPOSES:
        declare(name, f"when, where and how hard the '{kind}' disturbance acts in an episode (index)")
    return stream(name, seed, index)
