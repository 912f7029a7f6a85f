"""An installed plugin package that fails to import or to register is left out: every command goes on without it
after one warning line naming the package, its error and how to fix or uninstall it, with no traceback, and
``muble plugins`` lists it as broken. A package written against the previous release's imports and ``Agent.reset``
still runs its episodes, told what to change (docs/plugins.md, "The public API")."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from muble.plugins.manager import REPORTED_ENV
from tests.support.plugins import write_distribution

# Written against a module that does not exist (as a package written for another release of MuBlE would be).
BROKEN_IMPORT = "import muble\nfrom muble.core.weighing import Scale\n"
FIX = "pip uninstall acme-weights"
ERROR = "ModuleNotFoundError: No module named 'muble.core.weighing'"

# Imports fine; its agents hook raises, so its sensor (registered by a hook that worked) goes too.
BROKEN_HOOK = '''
import muble

class Clock(muble.Sensor):
    def read(self, env):
        return {"time": env.data.time}

@muble.hookimpl
def muble_register_sensors():
    return [muble.PluginRecord("acme_clock", Clock, "simulation time")]

@muble.hookimpl
def muble_register_agents():
    raise KeyError("agents.yaml")
'''

# The previous release's documented imports and reset signature; an agent that is the oracle underneath.
OLD_STYLE = '''
"""An agent package written against the previous release of MuBlE."""
from dataclasses import dataclass

import muble
from muble.core.descriptions import SceneIndex
from muble.core.program import execute
from muble.core.scene_io import load_scene


@dataclass
class OldOracleConfig:
    patience: int = 1


class OldOracle(muble.Agent):
    privileged = True

    def __init__(self, config: OldOracleConfig):
        self.inner = muble.get_registry().create("agent", "oracle")

    def reset(self, instruction, observation):
        self.inner.reset(instruction, observation)

    def act(self, instruction, observation):
        return self.inner.act(instruction, observation)


@muble.hookimpl
def muble_register_agents():
    return [muble.PluginRecord("old_oracle", OldOracle, "the oracle, written the old way", OldOracleConfig,
                               takes_config=True)]


@muble.hookimpl
def muble_config_searchpath():
    return ["pkg://acme_old.conf"]
'''


def _site(tmp_path: Path, name: str, module: str, source: str) -> Path:
    return write_distribution(tmp_path / name, name, {module: module}, {module: source})


def muble(args: list[str], *sites: Path, **env: str) -> subprocess.CompletedProcess:
    full = {k: v for k, v in os.environ.items() if k != REPORTED_ENV}
    full.update(PYTHONPATH=os.pathsep.join(str(s) for s in sites), MUJOCO_GL="egl", **env)
    return subprocess.run([sys.executable, "-m", "muble.app.cli", *args], capture_output=True, text=True, env=full,
                          timeout=600)


@pytest.fixture(scope="module")
def broken_sites(tmp_path_factory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("broken")
    return _site(tmp, "acme-weights", "acme_weights", BROKEN_IMPORT), _site(tmp, "acme-clock", "acme_clock",
                                                                             BROKEN_HOOK)


def _warned(stderr: str, *parts: str) -> list[str]:
    return [line for line in stderr.splitlines() if all(p in line for p in parts)]


def test_muble_plugins_lists_the_broken_packages_and_goes_on(broken_sites):
    result = muble(["plugins"], *broken_sites)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    (line,) = _warned(result.stderr, "plugin package 'acme-weights' left out", ERROR, FIX)
    assert "entry point 'acme_weights' (acme_weights) failed to import" in line
    (line,) = _warned(result.stderr, "plugin package 'acme-clock' left out", "pip uninstall acme-clock")
    assert "failed in muble_register_agents: KeyError: 'agents.yaml'" in line
    listing = result.stdout.split("\nBROKEN")
    assert len(listing) == 2 and "mujoco" in listing[0]  # everything else, then the broken ones
    assert "acme_clock" not in listing[0]  # its sensor went with it
    assert f"acme-weights:acme_weights (acme_weights)  failed to import: {ERROR}" in listing[1]
    assert FIX in listing[1] and "acme-clock:acme_clock" in listing[1]


def test_muble_plugins_json_has_a_row_per_broken_package(broken_sites):
    result = muble(["plugins", "--json"], *broken_sites)
    rows = json.loads(result.stdout)
    broken = {r["distribution"]: r for r in rows if r["kind"] == "broken"}
    assert broken.keys() == {"acme-weights", "acme-clock"}
    assert broken["acme-weights"]["error"] == ERROR and FIX in broken["acme-weights"]["fix"]
    assert {"oracle", "mujoco"} <= {r["name"] for r in rows}
    kinds = json.loads(muble(["plugins", "--json", "--kind", "sensor"], *broken_sites).stdout)
    assert {r["kind"] for r in kinds} == {"sensor"}


def test_a_hydra_command_goes_on_without_the_broken_packages(broken_sites, tmp_path):
    result = muble(["run", "dry_run=true", f"hydra.run.dir={tmp_path}"], *broken_sites)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "Traceback" not in result.stdout + result.stderr
    assert len(_warned(result.stderr, "'acme-weights' left out", ERROR, FIX)) == 1
    assert len(_warned(result.stderr, "'acme-clock' left out")) == 1
    assert (tmp_path / "manifest.json").is_file()


def test_a_config_naming_a_broken_package_s_plugin_is_an_unknown_name(broken_sites, tmp_path):
    result = muble(["run", "dry_run=true", "+sensors.enabled.acme_clock={}", f"hydra.run.dir={tmp_path}"],
                   *broken_sites)
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr[-3000:]
    assert "unknown sensor 'acme_clock'" in result.stderr


@pytest.fixture(scope="module")
def old_site(tmp_path_factory) -> Path:
    site = _site(tmp_path_factory.mktemp("old"), "acme-old", "acme_old", OLD_STYLE)
    package = site / "acme_old"
    package.mkdir()
    (site / "acme_old.py").rename(package / "__init__.py")
    (package / "conf" / "agent").mkdir(parents=True)
    (package / "conf" / "__init__.py").write_text("")
    (package / "conf" / "agent" / "old_oracle.yaml").write_text("defaults:\n  - old_oracle_schema\n  - _self_\n")
    return site


def test_a_package_written_against_the_old_imports_is_listed_and_told_what_to_change(old_site):
    result = muble(["plugins", "--kind", "agent"], old_site)
    assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr
    assert "old_oracle" in result.stdout and "BROKEN" not in result.stdout
    for old, new in (("muble.core.descriptions", "muble.programs.descriptions"),
                     ("muble.core.program", "muble.programs.program"), ("muble.core.scene_io", "muble.io.scene_io")):
        assert len(_warned(result.stderr, "plugin package 'acme-old'", f"{old} moved to {new}")) == 1, result.stderr


@pytest.mark.slow
def test_an_agent_with_the_old_reset_plays_a_physical_episode(old_site, tmp_path):
    result = muble(["run", "agent=old_oracle", f"hydra.run.dir={tmp_path}"], old_site)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "outcome: success" in result.stdout, result.stdout[-3000:]
    assert "Traceback" not in result.stderr
    assert len(_warned(result.stderr, "OldOracle.reset takes no keyword argument 'track' or 'mode'")) == 1
    assert len(_warned(result.stderr, "'acme-old'", "muble.core.program moved to muble.programs.program")) == 1
