"""The third-party example package: discovered through its entry point only, listed, selectable."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs" / "examples" / "muble-example-plugin"


@pytest.fixture(scope="module")
def example_site(tmp_path_factory) -> Path:
    """The example package installed (by pip, from its own pyproject) into a private folder."""
    target = tmp_path_factory.mktemp("example-site")
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                    "--target", str(target), str(EXAMPLE)], check=True, timeout=300)
    return target


def run(args: list[str], site: Path, **env: str) -> subprocess.CompletedProcess:
    full_env = {**os.environ, "PYTHONPATH": str(site), **env}
    return subprocess.run([sys.executable, "-m", "muble.app.cli", *args], capture_output=True, text=True,
                          env=full_env, timeout=300)


def test_example_is_listed_with_its_package(example_site):
    rows = json.loads(run(["plugins", "--json"], example_site).stdout)
    (row,) = [r for r in rows if r["name"] == "contact_count"]
    assert row == {"kind": "sensor", "name": "contact_count", "plugin": "example_contacts",
                   "distribution": "muble-example-plugin", "description": "number of active MuJoCo contacts"}


def test_example_is_not_loaded_when_autoload_is_disabled(example_site):
    rows = json.loads(run(["plugins", "--json"], example_site, MUBLE_DISABLE_PLUGIN_AUTOLOAD="1").stdout)
    assert "contact_count" not in {r["name"] for r in rows}


def test_example_config_is_selectable(example_site, tmp_path):
    result = run(["dry_run=true", "sensors=with_contacts", f"hydra.run.dir={tmp_path}"], example_site)
    assert result.returncode == 0, result.stderr
    config = json.loads((tmp_path / "manifest.json").read_text())["config"]
    assert config["sensors"]["enabled"]["contact_count"] == {"include_table": False}


def test_example_is_invisible_without_installation(tmp_path):
    result = subprocess.run([sys.executable, "-m", "muble.app.cli", "plugins", "--json"], capture_output=True,
                            text=True, timeout=300)
    assert "contact_count" not in {r["name"] for r in json.loads(result.stdout)}


def test_example_primitive_and_task_are_registered(example_site):
    rows = json.loads(run(["plugins", "--json"], example_site).stdout)
    found = {(r["kind"], r["name"]) for r in rows if r["distribution"] == "muble-example-plugin"}
    assert {("primitive", "tap"), ("task", "touch")} <= found


@pytest.mark.slow
def test_example_task_is_solved_by_the_builtin_oracle_with_physics(example_site, tmp_path):
    """A third-party primitive and task, written against the public API only: the built-in oracle plans through
    the task's next_actions, the action loop checks tap's typed parameters, the task judges the episode record."""
    result = run(["task=touch", "renderer=mujoco", f"hydra.run.dir={tmp_path}"], example_site, MUJOCO_GL="egl")
    assert result.returncode == 0, result.stderr[-3000:]
    assert "actions: tap(target=" in result.stdout and "outcome: success" in result.stdout, result.stdout
    config = json.loads((tmp_path / "manifest.json").read_text())["config"]
    assert config["agent"]["name"] == "oracle" and config["task"]["name"] == "touch"


def test_example_uses_only_the_public_api():
    source = (EXAMPLE / "muble_example_plugin" / "touch.py").read_text()
    imports = [line.split()[1] for line in source.splitlines() if line.startswith(("import ", "from "))]
    assert all(name in ("__future__", "dataclasses", "numpy", "muble") for name in imports), imports
