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

Every numpy generator MuBlE makes is made here (``tests/core/test_core_streams.py`` parses ``muble/``,
``muble_plugins/``, ``benchmarks/`` and ``scripts/`` and fails on one made anywhere else). Two older seedings are
kept, because files and results that must not change were made with them:

- ``split_seed``: the integer seed of a split (``seed * 1_000_003 + crc32(split)``), the entropy of every stream of
  a split's generation, so of every shipped split;
- ``legacy_stream``: numpy's ``default_rng(entropy)`` of a purpose declared with ``declare_legacy``, for draws that
  decide the oracle's physical episodes (its inverse-kinematics restarts, its descent seeds: the shipped sequence
  files) or recorded measurements (the random agent's row of docs/results.md, the probing pictures). New code does
  not use it: numpy pads a list of entropy with zeros, so ``default_rng([s, i]) == default_rng([s, i, 0])``, and
  two purposes seeded by lists of numbers can share a stream without anyone noticing (the learned planner's and
  parser's training did until they moved to named streams).
"""
from __future__ import annotations

import hashlib
import zlib

import numpy as np

PURPOSES: dict[str, str] = {}  # name -> what it draws
LEGACY: set[str] = set()  # the purposes drawn with their older seeding (``legacy_stream``)
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


def declare_legacy(name: str, about: str) -> str:
    """Declare a purpose that keeps its older seeding (``legacy_stream``); returns its name. Only for draws whose
    numbers recorded files or results depend on (see the module's doc)."""
    declare(name, about)
    LEGACY.add(name)
    return name


def _declared(purpose: str) -> None:
    if purpose not in PURPOSES:
        raise KeyError(f"random stream purpose '{purpose}' is not declared (muble.core.streams.declare); "
                       f"declared: {', '.join(sorted(PURPOSES))}")


def seed_sequence(purpose: str, seed: int, *key: int) -> np.random.SeedSequence:
    """The ``SeedSequence`` of ``purpose``'s stream for ``seed`` and its own numbers ``key``."""
    _declared(purpose)
    ints = [int(k) for k in key]
    if any(k < 0 for k in ints) or int(seed) < 0:
        raise ValueError(f"stream '{purpose}': seed and key must be non-negative integers, got {seed}, {ints}")
    return np.random.SeedSequence(int(seed), spawn_key=(purpose_key(purpose), *ints))


def stream(purpose: str, seed: int, *key: int) -> np.random.Generator:
    """A generator (PCG64) on ``purpose``'s stream for ``seed`` and ``key``."""
    return np.random.default_rng(seed_sequence(purpose, seed, *key))


def integer_seed(purpose: str, seed: int, *key: int) -> int:
    """A seed in [0, 2**63) for another library's generator (``torch.Generator().manual_seed``), drawn from
    ``purpose``'s stream for ``seed`` and ``key``: as distinct from every other purpose's as the streams are."""
    return int(seed_sequence(purpose, seed, *key).generate_state(1, np.uint64)[0] >> np.uint64(1))


def legacy_stream(purpose: str, *entropy: int) -> np.random.Generator:
    """``numpy.random.default_rng(list(entropy))``: the generator ``purpose`` (declared with ``declare_legacy``)
    was seeded with before named streams, kept so that what was recorded with it stays as it is. One number
    gives numpy's ``default_rng(n)``. Raises ``KeyError`` for a purpose not declared as legacy: new code draws
    from ``stream``."""
    _declared(purpose)
    if purpose not in LEGACY:
        raise KeyError(f"random stream purpose '{purpose}' keeps no older seeding (declare_legacy): draw from "
                       "muble.core.streams.stream(purpose, seed, *key)")
    ints = [int(e) for e in entropy]
    if not ints or any(e < 0 for e in ints):
        raise ValueError(f"stream '{purpose}': its entropy must be one or more non-negative integers, got {ints}")
    return np.random.default_rng(ints)


def split_seed(seed: int, split: str) -> int:
    """The seed of a split's generation (the entropy of every stream ``muble generate`` draws a split's index
    from): ``seed * 1_000_003 + crc32(split)``, a stable hash of the name (not Python's salted ``hash``). Every
    shipped split was generated from it, so it stays as it is."""
    if int(seed) < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed}")
    return int(seed) * 1_000_003 + zlib.crc32(str(split).encode())


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
# The physical episodes' own draws (muble.sim, the built-in primitives): one fixed seeding each, which decides the
# oracle's sequences in the shipped splits, so kept as it was (``legacy_stream``).
IK_RESTARTS = declare_legacy("sim.ik_restarts", "the collision world's inverse-kinematics restarts within the "
                             "joint limits (the world's seed; muble.sim.collision_world)")
PLACE_DESCENT = declare_legacy("primitive.place.descent_seeds", "the arm configurations a place tries when the "
                               "arm cannot descend from where it is (7: one fixed set; "
                               "muble_plugins.primitives.placement)")


def disturbance_stream(kind: str, seed: int, index: int) -> np.random.Generator:
    """The generator of the disturbance registered as ``kind`` for episode ``index`` of a run seeded ``seed``: its
    own purpose, ``episode.disturbance.<kind>``, declared on first use (muble.core.interfaces.Disturbance)."""
    name = f"episode.disturbance.{kind}"
    if name not in PURPOSES:
        declare(name, f"when, where and how hard the '{kind}' disturbance acts in an episode (index)")
    return stream(name, seed, index)
