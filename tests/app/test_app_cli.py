"""The command line and the Hydra configs: composition of every option, errors, multirun."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from muble.app.config import GROUP_OF_KIND, compose
from muble.core.errors import ConfigError
from muble.plugins.registry import get_registry

ROOT = Path(__file__).resolve().parents[2]
CONF = ROOT / "muble_conf"
GROUPS = sorted(p.name for p in CONF.iterdir() if p.is_dir() and not p.name.startswith("_"))


def muble(*args: str, env: dict | None = None, cwd: Path | None = None) -> subprocess.CompletedProcess:
    full_env = {**os.environ, "HYDRA_FULL_ERROR": "0", **(env or {})}
    return subprocess.run([sys.executable, "-m", "muble.app.cli", *args], capture_output=True, text=True,
                          env=full_env, cwd=cwd, timeout=300)


pytestmark = pytest.mark.usefixtures("clear_hydra")


def test_help_lists_commands():
    result = muble("--help")
    assert result.returncode == 0
    for command in ("run", "plugins", "generate", "eval", "render"):
        assert command in result.stdout


def test_unknown_command_exits_nonzero():
    result = muble("teleport")
    assert result.returncode == 2 and "valid commands" in result.stderr


def test_plugin_listing_names_kinds_and_packages():
    result = muble("plugins", "--json")
    assert result.returncode == 0, result.stderr
    rows = json.loads(result.stdout)
    kinds = {r["kind"] for r in rows}
    assert {"renderer", "planner", "primitive", "sensor", "task", "object_set", "agent"} <= kinds
    assert all(r["distribution"] == "muble" for r in rows if r["plugin"].startswith("builtin_"))
    table = muble("plugins", "--kind", "renderer")
    assert "mujoco" in table.stdout and "blender" in table.stdout and "muble:builtin_renderers" in table.stdout


def test_unknown_group_option_lists_valid_options(tmp_path):
    result = muble("renderer=nope", f"hydra.run.dir={tmp_path}")
    assert result.returncode != 0
    assert "nope" in result.stderr and "mujoco" in result.stderr and "blender" in result.stderr


def test_schemas_are_neither_listed_nor_selectable(tmp_path):
    listed = muble("renderer=nope", f"hydra.run.dir={tmp_path}")
    assert "_schema" not in listed.stderr and "mujoco" in listed.stderr
    assert "_schema" not in muble("plugins").stdout
    chosen = muble("renderer=mujoco_schema", "dry_run=true", f"hydra.run.dir={tmp_path}")
    assert chosen.returncode == 2 and "selects a schema" in chosen.stderr and "renderer=mujoco" in chosen.stderr
    assert not (tmp_path / "manifest.json").exists()


def test_mistyped_key_is_an_error(tmp_path):
    result = muble("renderer.widht=10", f"hydra.run.dir={tmp_path}")
    assert result.returncode != 0 and "widht" in result.stderr


def _options(group: str) -> list[str]:
    return sorted(p.stem for p in (CONF / group).glob("*.yaml"))


# Options that name a file they need (a trained checkpoint): built with their defaults, they refuse with a message
# naming the option to set.
NEEDS_A_FILE = {("agent", "learned_planner"): "agent.checkpoint|planner checkpoint"}
# Groups of another job's config (`muble train`), and the kind of plugin they build.
JOB_GROUPS = {"trainer": ("train", "trainer")}


@pytest.mark.parametrize("group,option", [(g, o) for g in GROUPS for o in _options(g) if g != "experiment"])
def test_every_option_composes_and_instantiates(group, option):
    config, kind = JOB_GROUPS.get(group, ("run", None))
    cfg = compose(config, [f"{group}={option}"])
    assert cfg[group] is not None
    registry = get_registry()
    kind = kind or {v: k for k, v in GROUP_OF_KIND.items()}.get(group)
    if kind is not None:
        assert cfg[group].name in registry.names(kind)
        if (group, option) in NEEDS_A_FILE:
            with pytest.raises(ConfigError, match=NEEDS_A_FILE[group, option]):
                registry.create(kind, cfg[group].name, cfg[group])
        else:
            registry.create(kind, cfg[group].name, cfg[group])
    if group == "sensors":
        for name, options in cfg.sensors.enabled.items():
            registry.create("sensor", name, options or {})


@pytest.mark.parametrize("experiment", _options("experiment"))
def test_every_experiment_composes(experiment):
    cfg = compose("run", [f"experiment={experiment}"])
    assert cfg.renderer.name in get_registry().names("renderer")


def test_render_takes_its_default_plugins_from_the_render_config():
    from muble.app.render import configured_plugins

    cfg = compose("render")
    assert configured_plugins() == (cfg.renderer.name, cfg.objects.name) == ("blender", "shopvrb2")


def test_dry_run_writes_manifest(tmp_path):
    result = muble("dry_run=true", f"hydra.run.dir={tmp_path}")
    assert result.returncode == 0, result.stderr
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["seeds"]["seed"] == 0 and manifest["versions"]["mujoco"].startswith("3.")


def test_multirun_sweep_over_two_options(tmp_path):
    result = muble("-m", "dry_run=true", "renderer=mujoco,blender", f"hydra.sweep.dir={tmp_path}")
    assert result.returncode == 0, result.stderr
    manifests = sorted(tmp_path.glob("*/manifest.json"))
    assert len(manifests) == 2
    renderers = {json.loads(m.read_text())["config"]["renderer"]["name"] for m in manifests}
    assert renderers == {"mujoco", "blender"}
