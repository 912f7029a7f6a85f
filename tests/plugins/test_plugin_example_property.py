"""A hidden property from a package outside MuBlE: the example package's ``temperature``, with its sampler, its
measuring primitive ``feel`` and two templates (a query and a superlative), written against the public API.

Found through the package's entry point (not installed: an installed-looking distribution on ``sys.path``), it
registers beside MuBlE's own five, which stay as they were; scenes generated with
``generator.physical_properties=[temperature]`` carry it; the built-in oracle solves its episodes, in the symbolic
world and with MuJoCo physics; and no agent ever sees the true temperature, only what it felt."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from muble import ActionCall, Outcome, get_registry
from muble.core import physical_properties
from muble.core.observation import MEASURED_EXTRA, leaks
from muble.programs.program import QUANTITIES, QUERY_STEPS
from muble.plugins import Registry, make_plugin_manager

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "docs" / "examples" / "muble-example-plugin" / "muble_example_plugin"
TEMPLATES = ("measure_temperature_single", "pick_up_temperature")
BUILTIN = ("weight", "stiffness", "friction", "com_offset", "rattles")


@pytest.fixture
def example(fake_distribution):
    """The example package as an installed distribution would be: its modules, template file and config folder
    under its entry point; its ``temperature`` module."""
    modules = {f"muble_example_plugin.{m.stem}": m.read_text() for m in PACKAGE.glob("*.py")}
    root = fake_distribution("muble-example-plugin", {"example_contacts": "muble_example_plugin"}, modules)
    shutil.copy(PACKAGE / "temperature_templates.yaml", root / "muble_example_plugin")
    shutil.copytree(PACKAGE / "conf", root / "muble_example_plugin" / "conf", dirs_exist_ok=True)
    import muble_example_plugin.temperature as temperature

    return temperature


def test_the_property_registers_from_the_entry_point_after_muble_s_own(example):
    registry = Registry(make_plugin_manager())
    assert not registry.broken
    assert list(registry.properties) == [*BUILTIN, "temperature"]
    prop = registry.properties["temperature"]
    assert prop is example.TEMPERATURE and prop.primitive == "feel" and prop.needs == "grasped"
    assert (prop.sampled_as, prop.scene_key, prop.stream) == ("temperature", "temperature_c", "scene.temperature")
    assert prop.superlatives == ("warmest", "coldest") and prop.domain == "temperature_superlative"
    assert (prop.tolerance, prop.margin, prop.measured_key) == (1.0, 5.0, "temperature_measured")
    assert registry.measures("feel") == "temperature"
    assert set(TEMPLATES) <= set(registry.names("task"))
    # MuBlE's own records are those its primitives plugin registers, unchanged.
    from muble_plugins.primitives.properties import BUILTIN as OWN

    assert [registry.properties[n] for n in BUILTIN] == list(OWN)


def test_everything_per_property_derives_it(example):
    get_registry()  # the registry with the package, as every table reads it
    assert "temperature" in physical_properties.PROPERTIES
    assert physical_properties.SCENE_KEYS["temperature"] == "temperature_c"
    assert MEASURED_EXTRA["temperature"] == "temperature_measured"
    assert QUERY_STEPS["query_temperature"] == "temperature"
    assert QUANTITIES["temperature"].apart(30.0, 25.0) and not QUANTITIES["temperature"].apart(30.0, 25.5)
    from muble_plugins.common.success import ANSWER_CHECKS

    check = ANSWER_CHECKS["temperature"]
    assert check([40.9], [41.7]) and not check([40.6], [41.7])


def test_without_the_package_there_is_no_temperature():
    get_registry.cache_clear()
    assert "temperature" not in physical_properties.PROPERTIES
    assert "temperature_measured" not in MEASURED_EXTRA.values()


def test_the_sampler_and_who_carries_it(example, object_set):
    rng = np.random.default_rng(0)
    values = [example.sample_temperature(rng, None, 100.0) for _ in range(500)]
    assert min(values) >= 4.0 and max(values) <= 60.0 and all(round(v, 1) == v for v in values)
    assert max(values) - min(values) > 50  # spread over the range
    carriers = set()
    for name in object_set.categories():
        spec = object_set.sample(np.random.default_rng(1), category=name)
        if example.holds_food_or_drink(spec, object_set.build(spec)):
            carriers.add(name)
    # In SHOP-VRB2 these are exactly the pickupable categories: food boxes, plates, boards and trays get none.
    assert carriers == {"bowl", "glass", "mug", "soda can", "thermos", "wine glass"}


def _symbolic_episodes(example, scenes: int):
    from muble_plugins.common.synthetic import sample_scenes

    registry = get_registry()
    tasks = {name: registry.create("task", name, {}) for name in TEMPLATES}
    for scene in sample_scenes(5, scenes, properties=True):
        for name, task in tasks.items():
            for ins in task.generate(scene, np.random.default_rng([5, scene.image_index])):
                yield name, task, ins, scene


def test_the_oracle_solves_every_generated_instruction_symbolically(example):
    from muble_plugins.agents.oracle import OracleAgent
    from muble_plugins.common.episodes import run_symbolic_episode

    seen = dict.fromkeys(TEMPLATES, 0)
    for name, task, ins, scene in _symbolic_episodes(example, 30):
        seen[name] += 1
        result = run_symbolic_episode(ins, scene, OracleAgent(task=task))
        assert result.outcome is Outcome.SUCCESS, (ins.instruction, [str(a) for a in result.actions])
        felt = [a.params for a in result.actions if a.name == "feel"]
        if name == "measure_temperature_single":
            (target,) = ins.program[-2]["output"]
            assert result.answer.value == [scene.object(target).extra["temperature_c"]] and len(felt) == 1
        else:
            compared = ins.program[-3]["output"]
            assert len(felt) == len(compared) >= 2  # each compared object felt once, nothing else
            values = {i: scene.object(i).extra["temperature_c"] for i in compared}
            pick = (max if ins.program[-2]["input_value"] == "warmest" else min)(values, key=values.get)
            assert ins.program[-1]["output"] == [pick] and result.final_scene.object(pick).extra["in_hand"]
    assert min(seen.values()) >= 10, seen


def test_the_symbolic_feel_needs_a_grasp_and_shows_only_what_was_felt(example):
    from muble.core.observation import agent_view
    from muble_plugins.common.symbolic import SymbolicWorld

    name, task, ins, scene = next(_symbolic_episodes(example, 5))
    world = SymbolicWorld(scene)
    result = world.apply(ActionCall("feel"))
    assert not result.success and "grasp an object first" in result.failure_reason
    view = world.observe(None, 0).scene
    assert leaks(view, world.measured) == [] and not any("temperature_c" in o.extra for o in view.objects)
    target = ins.program[-2]["output"][0]
    for call in task.ground_truth(ins, scene):
        world.apply(call)
    view = agent_view(world.scene, world.measured)
    assert view.object(target).extra["temperature_measured"] == scene.object(target).extra["temperature_c"]
    assert leaks(view, world.measured) == []
    assert leaks(view, {}) != []  # a felt temperature it did not measure would be a leak


@pytest.mark.gl
def test_generated_episodes_are_solved_by_the_oracle_with_physics(example, monkeypatch):
    """``muble generate``'s episodes (``split_episode``) of the two templates, with the property drawn: their
    scenes carry ``temperature_c``; the built-in oracle, in MuJoCo, feels each object the program compares (the
    probe touching it for the whole hold), answers within 1 °C and picks up the warmest or coldest; no observation
    holds the true temperature, under its key or as a number it did not feel."""
    from muble.app.config import compose
    from muble.episode.components import build_components, episode_runner, split_episode
    from muble_plugins.agents.oracle import OracleAgent
    from tests.episode import probes

    monkeypatch.setattr(probes, "HIDDEN_KEYS", (*probes.HIDDEN_KEYS, "temperature_c"))
    monkeypatch.setattr(probes, "MEASURES", {**probes.MEASURES, "feel": "temperature"})
    cfg = compose("generate", [f"dataset.templates=[{','.join(TEMPLATES)}]",
                               "generator.physical_properties=[temperature]", "seed=3"])
    components = build_components(cfg, renderer=False, task=False)
    runner = episode_runner(cfg, components)
    seen = set()
    for index in range(3):
        suited = split_episode(cfg, "val", index, components["object_set"])
        scene, ins = suited.scene, suited.instruction
        carried = [o for o in scene.objects if "temperature_c" in o.extra]
        assert carried and all(o.pickupable and o.name in example.CONTAINERS for o in carried)
        secrets = {float(o.extra["temperature_c"]) for o in carried}
        runner.agent = snoop = probes.Snoop(OracleAgent(), secrets)
        out = runner.execute(scene, ins, suited.task)
        result = out.result
        assert result.outcome is Outcome.SUCCESS, (ins.instruction, result.outcome, result.error)
        assert snoop.found == [], snoop.found
        feels = [s.result for s in result.steps if s.action.name == "feel"]
        assert feels and all(r.success and r.info["contact_s"] >= 0.95 * example.FEEL_HOLD_S for r in feels)
        if ins.template_id == "measure_temperature_single":
            (target,) = ins.program[-2]["output"]
            truth = scene.object(target).extra["temperature_c"]
            assert abs(result.answer.value[0] - truth) <= example.TOLERANCE_C
        else:
            assert len(feels) == len(ins.program[-3]["output"])
        seen.add(ins.template_id)
    assert seen == set(TEMPLATES), seen


@pytest.mark.gl
def test_feel_fails_with_an_empty_hand_and_its_probe_follows_the_first_order_law(example, generated_env):
    """The primitive in MuJoCo: with nothing between the fingers it fails with a reason and records nothing. The
    probe's law: no change without contact; with it, the gap to the object's temperature closes as exp(-t/tau),
    whatever the physics step."""
    feel = example.Feel()
    result = feel.execute(generated_env)
    assert not result.success and result.failure_reason == example.Feel.empty_hand
    assert not any("temperature" in m for m in generated_env.measurements.values())
    # The law itself: no contact, no change; 5 time constants of contact close all but e^-5 of the gap.
    assert example.probe_step(22.0, 60.0, 0.002, touching=False) == 22.0
    probe = 22.0
    for _ in range(int(example.FEEL_HOLD_S / 0.002)):
        probe = example.probe_step(probe, 60.0, 0.002, touching=True)
    assert abs(probe - (60.0 - 38.0 * np.exp(-example.FEEL_HOLD_S / example.PROBE_TIME_CONSTANT_S))) < 1e-6
    assert example.probe_step(22.0, 60.0, 2.0, touching=True) == pytest.approx(probe)


def test_the_package_imports_only_the_public_api():
    from tests.plugins.test_plugin_public_api import muble_imports, public_api, unlisted

    for module in ("temperature.py", "__init__.py"):
        source = (PACKAGE / module).read_text()
        assert unlisted(muble_imports(source), public_api()) == [], module
