"""Every task and agent yaml composes against its plugin's schema and instantiates through the registry."""
from __future__ import annotations

from pathlib import Path

import pytest
from hydra import compose, initialize_config_module
from hydra.core.global_hydra import GlobalHydra

from muble import Agent, Task, get_registry
from muble.app.config import CONFIG_MODULE, HYDRA_VERSION_BASE, register_configs

CONF = Path(__file__).resolve().parents[2] / "muble_conf"
TASK_YAMLS = sorted(p.stem for p in (CONF / "task").glob("*.yaml"))
AGENT_YAMLS = sorted(p.stem for p in (CONF / "agent").glob("*.yaml"))


@pytest.fixture()
def hydra():
    GlobalHydra.instance().clear()
    register_configs(get_registry())
    with initialize_config_module(config_module=CONFIG_MODULE, version_base=HYDRA_VERSION_BASE):
        yield
    GlobalHydra.instance().clear()


def test_every_task_plugin_has_a_yaml():
    assert set(get_registry().names("task")) <= set(TASK_YAMLS)
    assert {"oracle", "random"} <= set(AGENT_YAMLS)


@pytest.mark.parametrize("name", TASK_YAMLS)
def test_task_yaml_composes_and_instantiates(hydra, name):
    cfg = compose(overrides=[f"+task={name}"])
    assert isinstance(get_registry().create("task", cfg.task.name, cfg.task), Task)


# Agents whose defaults name a file they need (a trained checkpoint): built as they are, they refuse and say what.
NEEDS_A_FILE = {"learned_planner": "planner checkpoint"}


@pytest.mark.parametrize("name", AGENT_YAMLS)
def test_agent_yaml_composes_and_instantiates(hydra, name):
    from muble import ConfigError

    cfg = compose(overrides=[f"+agent={name}"])
    if name in NEEDS_A_FILE:
        with pytest.raises(ConfigError, match=NEEDS_A_FILE[name]):
            get_registry().create("agent", cfg.agent.name, cfg.agent)
        return
    assert isinstance(get_registry().create("agent", cfg.agent.name, cfg.agent), Agent)


def test_mistyped_task_option_is_an_error(hydra):
    from muble import ConfigError

    cfg = compose(overrides=["+task=stack_order"])
    with pytest.raises(ConfigError, match="instructions_per_scene"):
        get_registry().create("task", "stack_order", {**cfg.task, "instructions_per_scen": 2})
