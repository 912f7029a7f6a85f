"""Named random streams: every purpose's streams are distinct from every other's by construction, and the scene,
instruction and task-mix code draws only from them."""
from __future__ import annotations

import ast
import itertools
from pathlib import Path

import numpy as np
import pytest

from muble.core import streams

ROOT = Path(__file__).resolve().parents[2]
# The modules that decide a split's episodes: no random stream of theirs may be made anywhere but streams.
EPISODE_MODULES = ["muble/generation", "muble/episode", "muble/dataset"]


def test_every_declared_purpose_has_its_own_key():
    keys = {name: streams.purpose_key(name) for name in streams.PURPOSES}
    assert len(set(keys.values())) == len(keys), keys
    for name in ("scene.objects", "scene.layout", "scene.camera_jitter", "scene.lamp_jitter",
                 "episode.instruction", "split.template_mix", "split.count_mix"):
        assert name in streams.PURPOSES


def test_the_instruction_stream_and_every_scene_stream_are_distinct():
    """Every pair of purposes, over seeds and keys that collide as plain integer lists (the instruction stream was
    once ``[seed, index, 1]``, the same list as a scene's first resample): distinct spawn keys, distinct draws."""
    seeds, keys = (0, 1, 2), [(0,), (1,), (0, 1), (1, 1), (3, 0), (3, 1)]
    seen: dict[tuple, tuple] = {}
    for purpose, seed, key in itertools.product(sorted(streams.PURPOSES), seeds, keys):
        seq = streams.seed_sequence(purpose, seed, *key)
        ident = (seq.entropy, seq.spawn_key)
        assert ident not in seen, (purpose, seed, key, seen.get(ident))
        seen[ident] = (purpose, seed, key)
        draws = tuple(streams.stream(purpose, seed, *key).integers(0, 2**63, size=2))
        assert draws not in seen, (purpose, seed, key, seen[draws])
        seen[draws] = (purpose, seed, key)
    assert len(seen) == 2 * len(streams.PURPOSES) * len(seeds) * len(keys)


def test_a_stream_is_a_pure_function_of_purpose_seed_and_key():
    a = streams.stream(streams.SCENE_LAYOUT, 5, 3, 0).random(4)
    assert np.array_equal(a, streams.stream(streams.SCENE_LAYOUT, 5, 3, 0).random(4))
    assert not np.array_equal(a, streams.stream(streams.SCENE_LAYOUT, 5, 3, 1).random(4))


def test_undeclared_purposes_and_colliding_names_are_refused(monkeypatch):
    with pytest.raises(KeyError, match="not declared"):
        streams.stream("no.such.purpose", 0, 1)
    with pytest.raises(ValueError, match="non-negative"):
        streams.stream(streams.SCENE_LAYOUT, 0, -1)
    monkeypatch.setitem(streams._KEYS, streams.purpose_key("plugin.friction"), "another.name")
    with pytest.raises(ValueError, match="has the key of 'another.name'"):
        streams.declare("plugin.friction", "a plugin's friction draws")


def _random_calls(path: Path) -> list[str]:
    """Calls that make a numpy stream (default_rng, Generator, RandomState, SeedSequence, np.random.*) in a file."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call):
            name = ast.unparse(node.func)
            if name.split(".")[-1] in ("default_rng", "RandomState", "SeedSequence", "Generator", "seed") \
                    or name.startswith(("np.random.", "numpy.random.")):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno}: {name}")
    return found


def test_the_modules_that_decide_episodes_draw_only_from_named_streams():
    calls = [c for folder in EPISODE_MODULES for p in sorted((ROOT / folder).rglob("*.py")) for c in _random_calls(p)]
    assert calls == [], calls
    # And the check sees such a call where there is one.
    assert _random_calls(ROOT / "muble/core/streams.py")


def test_generating_a_scene_draws_from_the_scene_instruction_and_mix_streams(monkeypatch):
    """The purposes one index of a split draws from, spied on while the split's code path runs (no physics: the
    generator's costly checks are off)."""
    from muble.generation import task_mix
    from muble.generation.generator import SceneGenerator
    from muble.episode.runner import instruction_rng
    from muble.plugins.registry import get_registry

    used: list[str] = []
    real = streams.stream

    def spy(purpose, seed, *key):
        used.append(purpose)
        return real(purpose, seed, *key)

    monkeypatch.setattr(streams, "stream", spy)
    generator = SceneGenerator({"object_set": "shopvrb2", "renderer": "mujoco", "reach_check": False,
                                "stability": False, "stack_check": False, "min_visible_pixels": 0,
                                "camera_jitter_m": 0.01, "lamp_jitter": 0.1}, seed=3)
    tasks = {name: get_registry().create("task", name, {}) for name in ("move_single", "stack_simple")}
    try:
        task_mix.suited_scene(generator, tasks, [1.0, 1.0], 3, 0, lambda i: instruction_rng(3, i))
    finally:
        generator.close()
    assert {streams.SCENE_OBJECTS, streams.SCENE_LAYOUT, streams.CAMERA_JITTER, streams.LAMP_JITTER,
            streams.INSTRUCTION, streams.TEMPLATE_MIX, streams.COUNT_MIX} <= set(used), sorted(set(used))
