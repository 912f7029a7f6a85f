"""Each plugin option has one definition: its config dataclass declares its default and its bounds, the registry
checks what it is given against it, and no factory declares a default of its own for it (which could drift from
the dataclass's) or checks a bound again."""
from __future__ import annotations

import dataclasses
import inspect
import shutil
from pathlib import Path

import pytest

from muble import ConfigError, PluginRecord, bounded
from muble.plugins import Provided, Registry, make_plugin_manager

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "muble-example-plugin" / "muble_example_plugin"

# Built-in records with a config that are called with keyword arguments instead of the checked instance, each with
# why it cannot take it.
KEYWORD_FACTORIES: dict[tuple[str, str], str] = {}


def redeclared_defaults(record: PluginRecord) -> list[str]:
    """The options of ``record.config`` to which the factory's signature gives a default of its own."""
    options = {f.name for f in dataclasses.fields(record.config)}
    parameters = inspect.signature(record.factory).parameters.values()
    return sorted(p.name for p in parameters if p.name in options and p.default is not inspect.Parameter.empty)


def offenders(provided: list[Provided]) -> dict[str, list[str]]:
    found = {f"{p.kind} '{p.record.name}' ({p.distribution})": redeclared_defaults(p.record)
             for p in provided if p.record.config is not None}
    return {name: options for name, options in found.items() if options}


def test_no_registered_factory_redeclares_a_default_of_its_config(muble_registry):
    configured = [p for p in muble_registry.all() if p.record.config is not None]
    assert {p.kind for p in configured} >= {"renderer", "planner", "task", "object_set", "agent", "trainer"}
    assert offenders(configured) == {}, "declare each default once, in the config dataclass (takes_config=True)"


def test_the_example_package_declares_each_default_once(fake_distribution):
    modules = {f"muble_example_plugin.{m.stem}": m.read_text() for m in EXAMPLE.glob("*.py")}
    root = fake_distribution("muble-example-plugin", {"example_contacts": "muble_example_plugin"}, modules)
    shutil.copy(EXAMPLE / "temperature_templates.yaml", root / "muble_example_plugin")  # its template tasks
    registry = Registry(make_plugin_manager())
    example = [p for p in registry.all() if p.distribution == "muble-example-plugin"]
    assert {(p.kind, p.record.name) for p in example if p.record.config} == {
        ("sensor", "contact_count"), ("task", "touch"), ("agent", "greedy"), ("disturbance", "nudge"),
        ("task", "measure_temperature_single"), ("task", "pick_up_temperature")}
    assert offenders(example) == {}
    sensor = registry.create("sensor", "contact_count", {"include_table": False})
    assert sensor.include_table is False
    with pytest.raises(ConfigError, match="lift_height must be 0.01..0.4"):
        registry.create("agent", "greedy", {"lift_height": 0.5})


def test_built_in_factories_take_their_checked_config(muble_registry):
    built_in = [p for p in muble_registry.all() if p.distribution == "muble" and p.record.config is not None]
    takes_keywords = {(p.kind, p.record.name) for p in built_in if not p.record.takes_config}
    assert takes_keywords == set(KEYWORD_FACTORIES)
    for kind, name in KEYWORD_FACTORIES:
        assert not dataclasses.fields(muble_registry.get(kind, name).record.config)


def test_a_redeclared_default_is_found():
    @dataclasses.dataclass
    class StepConfig:
        step: float = bounded(0.005, gt=0)
        speed: float = 0.15

    def make(step: float = 0.01, speed: float = 0.15, label: str = "") -> None: ...

    def make_from(config: StepConfig, label: str = "") -> None: ...

    assert redeclared_defaults(PluginRecord("line", make, "", StepConfig)) == ["speed", "step"]
    assert redeclared_defaults(PluginRecord("line", make_from, "", StepConfig, takes_config=True)) == []


def _ompl():
    from muble_plugins.planners.ompl_planner import OmplPlanner, OmplPlannerConfig

    return OmplPlanner, OmplPlannerConfig, {}


def _straight_line():
    from muble_plugins.planners.straight_line import StraightLinePlanner, StraightLinePlannerConfig

    return StraightLinePlanner, StraightLinePlannerConfig, {}


def _random():
    from muble_plugins.agents.random_agent import RandomAgent, RandomConfig

    return RandomAgent, RandomConfig, {}


def _llm():
    from muble_plugins.llm.agent import LlmAgent
    from muble_plugins.llm.config import LlmConfig

    return LlmAgent, LlmConfig, {}


def _objects():
    from muble_plugins.objects.catalogue import ObjectSetConfig
    from muble_plugins.objects.ycb import YcbObjects

    return YcbObjects, ObjectSetConfig, {"cache_dir": None}


def _task():
    from muble_plugins.tasks.tasks import TASK_CLASSES, ShopVrb2TaskConfig

    return TASK_CLASSES["stack_order"], ShopVrb2TaskConfig, {}


def _parser():
    from muble_plugins.learned.config import ParserTrainerConfig
    from muble_plugins.learned.parser import ParserTrainer

    return ParserTrainer, ParserTrainerConfig, {}


def _recogniser():
    from muble_plugins.learned.config import RecogniserTrainerConfig
    from muble_plugins.learned.recogniser import RecogniserTrainer

    return RecogniserTrainer, RecogniserTrainerConfig, {}


# A class built directly (tests, benchmarks, scripts) with keyword options: a value the config's bounds refuse,
# or a key it lacks, is the registry's ConfigError naming the option.
DIRECT = [
    pytest.param(_ompl, {"check_budget": 0}, "planner 'ompl': value out of range: check_budget must be >= 1",
                 id="ompl"),
    pytest.param(_straight_line, {"stepp": 0.01}, "planner 'straight_line' has no option.*valid options: step, ",
                 id="straight_line"),
    pytest.param(_random, {"stop_probability": "often"}, "agent 'random': option stop_probability", id="random"),
    pytest.param(_llm, {"max_tokens": 0}, "agent 'llm': value out of range: max_tokens must be >= 1", id="llm"),
    pytest.param(_objects, {"inner_fraction": 1.0}, "object_set 'ycb': value out of range: inner_fraction must "
                 "be > 0 and < 1", id="object_set"),
    pytest.param(_task, {"instructions_per_scen": 2}, "task 'stack_order' has no option.*instructions_per_scene",
                 id="task"),
    pytest.param(_parser, {"dropout": 1.0}, "trainer 'parser': value out of range: dropout must be >= 0 and < 1",
                 id="parser"),
    pytest.param(_recogniser, {"crop_size": 8}, "trainer 'recogniser': value out of range: crop_size must be >= 16",
                 id="recogniser"),
]


@pytest.mark.parametrize(("plugin", "bad", "message"), DIRECT)
def test_direct_construction_has_the_config_defaults_and_checks(plugin, bad, message):
    cls, schema, required = plugin()
    assert cls(**required).config == schema(**required)
    assert cls(schema(**required)).config == schema(**required)
    with pytest.raises(ConfigError, match=message):
        cls(**required, **bad)


def test_learned_planner_agent_takes_its_config_and_a_network_in_memory():
    from muble_plugins.learned.agent import LearnedPlannerAgent
    from muble_plugins.learned.config import LearnedPlannerConfig

    network = object()
    agent = LearnedPlannerAgent(network=network, parser="parser.pt")
    assert agent.net is network and agent.config == LearnedPlannerConfig(parser="parser.pt")
    assert agent.parser_path == "parser.pt" and agent.recogniser_path is None
    with pytest.raises(ConfigError, match="agent 'learned_planner' has no option.*checkpoint"):
        LearnedPlannerAgent(network=network, checkpiont="planner.pt")
