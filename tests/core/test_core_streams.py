"""Named random streams: every purpose's streams are distinct from every other's by construction, no numpy
generator is made anywhere but ``muble/core/streams.py`` (MuBlE, its plugins, benchmarks and scripts, read with
``ast``), the learned trainers' streams that numpy's padding of entropy once made one are apart, and the older
seedings that shipped files and recorded results depend on give the numbers they gave."""
from __future__ import annotations

import ast
import itertools
from pathlib import Path

import numpy as np
import pytest

from muble.core import streams

ROOT = Path(__file__).resolve().parents[2]


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


# Where numpy generators may not be made: everything but muble/core/streams.py (tests make their own).
SCANNED = ["muble", "muble_plugins", "benchmarks", "scripts"]
STREAMS_MODULE = ROOT / "muble/core/streams.py"
# numpy.random's names that make a generator or a seed, or draw from (or seed) its global one.
MAKERS = {"default_rng", "RandomState", "Generator", "SeedSequence", "PCG64", "PCG64DXSM", "MT19937", "Philox",
          "SFC64", "BitGenerator"}


def _numpy_random_names(tree: ast.Module) -> tuple[set[str], set[str], set[str]]:
    """(names bound to numpy, names bound to numpy.random, names bound to a name of numpy.random) in a module."""
    numpy, random, members = set(), set(), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == "numpy":
                    numpy.add(alias.asname or "numpy")
                elif alias.name == "numpy.random":
                    (random if alias.asname else numpy).add(alias.asname or "numpy")
        elif isinstance(node, ast.ImportFrom) and node.module in ("numpy", "numpy.random"):
            for alias in node.names:
                if node.module == "numpy" and alias.name == "random":
                    random.add(alias.asname or "random")
                elif node.module == "numpy.random":
                    members.add(alias.asname or alias.name)
    return numpy, random, members


def _generators_made(source: str, where: str) -> list[str]:
    """Every numpy generator made, or numpy global generator used, in ``source``: a call of ``default_rng``,
    ``RandomState``, ``Generator``, ``SeedSequence`` or a bit generator, ``np.random.seed`` or any module-level
    ``np.random`` function (``rand``, ``choice``, ``shuffle`` ...), through whatever names numpy was imported as;
    and a reference to one of the makers (``f = np.random.default_rng``). ``np.random.Generator`` as a type is
    not one."""
    tree = ast.parse(source)
    numpy, random, members = _numpy_random_names(tree)

    def numpy_random_member(node: ast.AST) -> str | None:
        """``x`` when ``node`` is ``<numpy>.random.x`` or ``<numpy.random>.x``; ``node``'s name when it is a name
        imported from numpy.random."""
        if isinstance(node, ast.Attribute):
            base = node.value
            if isinstance(base, ast.Name) and base.id in random:
                return node.attr
            if isinstance(base, ast.Attribute) and base.attr == "random" and isinstance(base.value, ast.Name) \
                    and base.value.id in numpy:
                return node.attr
        if isinstance(node, ast.Name) and node.id in members:
            return node.id
        return None

    found, called = [], set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            name = numpy_random_member(node.func)
            if name is not None:
                found.append(f"{where}:{node.lineno}: {ast.unparse(node.func)}(...)")
                called.add(id(node.func))
    made_by_reference = MAKERS - {"Generator", "BitGenerator"}  # those two are also types in annotations
    for node in ast.walk(tree):
        if id(node) not in called and isinstance(node, (ast.Attribute, ast.Name)) \
                and isinstance(node.ctx, ast.Load) and numpy_random_member(node) in made_by_reference:
            found.append(f"{where}:{node.lineno}: {ast.unparse(node)}")
    return found


def test_no_numpy_generator_is_made_outside_the_streams_module():
    """Every random number of MuBlE, its plugins, benchmarks and scripts comes through ``muble.core.streams``."""
    made = []
    for folder in SCANNED:
        for path in sorted((ROOT / folder).rglob("*.py")):
            if path != STREAMS_MODULE and "build" not in path.relative_to(ROOT).parts:
                made.extend(_generators_made(path.read_text(), str(path.relative_to(ROOT))))
    assert made == [], "make generators with muble.core.streams.stream (declare the purpose):\n" + "\n".join(made)
    # And the streams module itself is where they are made.
    assert _generators_made(STREAMS_MODULE.read_text(), "streams")


@pytest.mark.parametrize("source", [
    "import numpy as np\nrng = np.random.default_rng(7)",
    "import numpy\nrng = numpy.random.default_rng([1, 2])",
    "import numpy as np\nnp.random.seed(3)",
    "import numpy as np\nx = np.random.uniform(0, 1)",
    "import numpy as np\nnp.random.shuffle(items)",
    "import numpy as np\nstate = np.random.RandomState(0)",
    "import numpy as np\ng = np.random.Generator(np.random.PCG64(1))",
    "import numpy as np\nseq = np.random.SeedSequence(5, spawn_key=(1,))",
    "from numpy.random import default_rng\nrng = default_rng(1)",
    "from numpy.random import default_rng as make\nrng = make(1)",
    "from numpy import random as npr\nx = npr.random()",
    "import numpy.random as npr\nx = npr.default_rng(0)",
    "import numpy as np\nmake = np.random.default_rng",
])
def test_the_check_finds_every_way_of_making_a_generator(source):
    assert _generators_made(source, "example")


@pytest.mark.parametrize("source", [
    "import numpy as np\ndef f(rng: np.random.Generator) -> np.random.Generator: return rng",
    "import torch\ng = torch.Generator().manual_seed(3)",
    "from muble.core import streams\nrng = streams.stream('scene.layout', 0, 1)",
    "import random\nrandom.seed(0)",
])
def test_the_check_leaves_types_streams_and_other_libraries_alone(source):
    assert _generators_made(source, "example") == []


def _streams_drawn(monkeypatch, run) -> list[tuple]:
    """(purpose, seed, key) of every stream ``run()`` draws through ``muble.core.streams.stream``."""
    used: list[tuple] = []
    real = streams.stream

    def spy(purpose, seed, *key):
        used.append((purpose, seed, key))
        return real(purpose, seed, *key)

    monkeypatch.setattr(streams, "stream", spy)
    run()
    return used


def test_the_streams_that_numpy_padding_made_one_in_the_learned_training_are_apart(monkeypatch):
    """numpy pads a list of entropy with zeros: ``[s, i, 6]`` and ``[s, i, 6, 0]`` were one stream, so the learned
    planner's property draws of a scene were its first roll-out's, and the parser's scene stream ``[s, p, i]`` its
    first instruction's ``[s, p, i, 0]``. Their streams now are named purposes: every stream one scene of either
    trainer draws is its own, and the pairs that coincided draw differently."""
    pytest.importorskip("torch")
    from muble_plugins.common import synthetic
    from muble_plugins.learned import parser, planner

    def draws(make) -> tuple:
        return tuple(make().integers(0, 2**63, size=4))

    seed, index = 3, 5
    assert draws(lambda: np.random.default_rng([seed, index, 6])) == \
        draws(lambda: np.random.default_rng([seed, index, 6, 0]))  # numpy's padding, as it was used
    assert draws(lambda: streams.stream(synthetic.PROPERTIES_STREAM, seed, 0, index)) != \
        draws(lambda: streams.stream(planner.ROLLOUT_STREAM, seed, 0, index, 0))
    assert draws(lambda: streams.stream(parser.SCENE_STREAM, seed, 0, index)) != \
        draws(lambda: streams.stream(parser.INSTRUCTION_STREAM, seed, 0, index, 0))
    # A key and the same key with a zero appended are two streams of one purpose too (spawn keys are not padded).
    assert draws(lambda: streams.stream(parser.SCENE_STREAM, seed, 0, index)) != \
        draws(lambda: streams.stream(parser.SCENE_STREAM, seed, 0, index, 0))

    used = _streams_drawn(monkeypatch, lambda: planner._scene_rollouts(seed, index, False, 0.2, 0.1, [], []))
    used += _streams_drawn(monkeypatch, lambda: planner.scene_for(seed, index, True))
    used += _streams_drawn(monkeypatch, lambda: parser.build_pairs(seed, 0, 2))
    assert {synthetic.PROPERTIES_STREAM, planner.ROLLOUT_STREAM, parser.SCENE_STREAM,
            parser.INSTRUCTION_STREAM} <= {purpose for purpose, _, _ in used}
    states = {}
    for purpose, s, key in used:
        state = tuple(streams.seed_sequence(purpose, s, *key).generate_state(4))
        assert states.setdefault(state, (purpose, key)) == (purpose, key), (purpose, key, states[state])


def test_the_older_seedings_give_the_numbers_they_gave():
    """What files and results were made with: a split's seed and the legacy generators (the oracle's descent seeds
    and inverse-kinematics restarts, the random agent), which only their declared purposes may use."""
    import zlib

    from muble.dataset import production

    assert streams.split_seed(7, "mini") == 7 * 1_000_003 + zlib.crc32(b"mini")
    assert production.split_seed is streams.split_seed
    assert np.array_equal(streams.legacy_stream(streams.PLACE_DESCENT, 7).random(6),
                          np.random.default_rng(7).random(6))
    assert np.array_equal(streams.legacy_stream(streams.IK_RESTARTS, 4, 9).random(3),
                          np.random.default_rng([4, 9]).random(3))
    with pytest.raises(KeyError, match="keeps no older seeding"):
        streams.legacy_stream(streams.SCENE_LAYOUT, 7)
    with pytest.raises(ValueError, match="non-negative"):
        streams.legacy_stream(streams.PLACE_DESCENT)
    seed = streams.integer_seed(streams.SCENE_LAYOUT, 3, 1)
    assert 0 <= seed < 2**63 and seed == streams.integer_seed(streams.SCENE_LAYOUT, 3, 1)
    assert seed != streams.integer_seed(streams.SCENE_OBJECTS, 3, 1)


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
