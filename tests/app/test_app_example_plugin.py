"""The third-party example package: discovered through its entry point only, listed, selectable; its primitive,
task and agent work in the symbolic and the physical world."""
from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from muble import ActionResult, Observation, ObservationMode, Outcome, Track, get_registry
from muble.core.observation import agent_instruction
from muble.episode.loop import run_episode

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
    assert {("primitive", "tap"), ("task", "touch"), ("agent", "greedy"), ("disturbance", "nudge"),
            ("property", "temperature"), ("primitive", "feel"), ("task", "measure_temperature_single"),
            ("task", "pick_up_temperature")} <= found


@pytest.mark.slow
def test_example_property_is_generated_and_solved_by_the_oracle_from_the_command_line(example_site, tmp_path):
    """A hidden property from a package outside MuBlE, installed with pip: ``muble generate`` draws it for the
    scenes (``generator.physical_properties=[temperature]``) and makes episodes of its two templates, whose
    ground-truth sequences the oracle runs with physics; ``muble eval`` then solves every one, answering within
    the property's tolerance, and the agent's records hold what it felt, never the scene's key."""
    root, templates = tmp_path / "ds", "measure_temperature_single,pick_up_temperature"
    result = run(["generate", "dataset.splits=[val]", "dataset.sizes=[4]", "dataset.executor=serial", "seed=5",
                  f"dataset.templates=[{templates}]", "generator.physical_properties=[temperature]",
                  f"dataset.root={root}", f"hydra.run.dir={tmp_path / 'gen'}"], example_site, MUJOCO_GL="egl")
    assert result.returncode == 0, result.stderr[-3000:]
    scenes = [json.loads(p.read_text()) for p in sorted((root / "val" / "scenes").glob("*.json"))]
    assert len(scenes) == 4 and all(any("temperature_c" in o for o in s["objects"]) for s in scenes)
    out = tmp_path / "eval"
    result = run(["eval", "agent=oracle", f"dataset.root={root}", "dataset.executor=serial", "dataset.workers=1",
                  f"hydra.run.dir={out}"], example_site, MUJOCO_GL="egl")
    assert result.returncode == 0, result.stderr[-3000:]
    records = [json.loads(line) for line in (out / "episodes_val.jsonl").read_text().splitlines()]
    assert [r["outcome"] for r in records] == ["success"] * 4, [(r["outcome"], r["error"]) for r in records]
    assert all("feel()" in r["primitives"] for r in records)
    for record in records:
        instruction = json.loads((root / "val" / "instructions" / f"SHOP_VRB2_val_{record['index']:06d}.json")
                                 .read_text())
        if record["template"] == "measure_temperature_single":
            truth = instruction["program"][-1]["output"]  # the queried object's true temperature
            assert abs(record["answer"][0] - truth[0]) <= 1.0, (record["answer"], truth)
        assert "temperature_c" not in json.dumps(record)
    assert {r["template"] for r in records} == set(templates.split(","))


@pytest.mark.slow
def test_example_disturbance_acts_in_frozen_episodes_the_oracle_still_solves(example_site, tmp_path):
    """A disturbance from a package outside MuBlE: registered through its entry point, enabled from the command
    line, it draws from its own stream, pushes through MuJoCo, lands in the records, and the closed-loop oracle
    still solves the episodes of the frozen split it runs on."""
    out = tmp_path / "run"
    result = run(["eval", "protocol=shopvrb2_v2", "agent=oracle", "+disturbances.enabled.nudge={}",
                  "evaluation.limit=4", "dataset.workers=1", f"hydra.run.dir={out}"], example_site, MUJOCO_GL="egl",
                 MUBLE_DATA_CACHE=str(tmp_path / "cache"))
    assert result.returncode == 0, result.stderr[-3000:]
    records = [json.loads(line) for line in (out / "episodes_mini.jsonl").read_text().splitlines()]
    assert len(records) == 4
    events = [e for r in records for e in r["disturbances"]]
    assert [e["kind"] for e in events] == ["nudge"] * 4 and all(r["disturbances_planned"] == 1 for r in records)
    assert all(abs(e["force"][2]) == 0.0 and np.hypot(*e["force"][:2]) > 0 for e in events)
    assert [r["outcome"] for r in records] == ["success"] * 4, [(r["outcome"], r["error"]) for r in records]


@pytest.mark.slow
def test_example_task_is_solved_by_the_builtin_oracle_with_physics(example_site, tmp_path):
    """A third-party primitive and task, written against the public API only: the built-in oracle plans through
    the task's next_actions, the action loop checks tap's typed parameters, the task judges the episode record."""
    result = run(["task=touch", "renderer=mujoco", f"hydra.run.dir={tmp_path}"], example_site, MUJOCO_GL="egl")
    assert result.returncode == 0, result.stderr[-3000:]
    assert "step 1: tap(target=" in result.stdout and "outcome: success" in result.stdout, result.stdout
    # Each step is printed once: logged as it happens, not repeated in the summary.
    assert result.stdout.count("tap(target=") == 1, result.stdout
    config = json.loads((tmp_path / "manifest.json").read_text())["config"]
    assert config["agent"]["name"] == "oracle" and config["task"]["name"] == "touch"


@pytest.mark.parametrize("module", ["touch.py", "agent.py", "nudge.py"])
def test_example_uses_only_the_public_api(module):
    source = (EXAMPLE / "muble_example_plugin" / module).read_text()
    imports = [line.split()[1] for line in source.splitlines() if line.startswith(("import ", "from "))]
    allowed = ("__future__", "collections.abc", "dataclasses", "logging", "numpy", "muble")
    assert all(name in allowed for name in imports), imports


@pytest.fixture
def greedy_agent(monkeypatch):
    """The example package's agent class, loaded from its source file. Not through sys.path: a registry built
    while the package is importable would list its plugins for every later test of the process."""
    name = "example_greedy_agent"
    spec = importlib.util.spec_from_file_location(name, EXAMPLE / "muble_example_plugin" / "agent.py")
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, name, module)  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module.GreedyAgent


@pytest.fixture(scope="module")
def symbolic_episodes():
    """(template, instruction, scene) of every built-in template over a few synthetic scenes."""
    from muble_plugins.common.synthetic import sample_scenes

    registry = get_registry()
    out = []
    for scene in sample_scenes(31, 6):
        for name in registry.names("task"):
            task = registry.create("task", name)
            out += [(name, ins, scene) for ins in task.generate(scene, np.random.default_rng([31, scene.image_index]))]
    return out


def test_greedy_solves_the_single_object_templates_and_stops_on_the_others(greedy_agent, symbolic_episodes):
    """In the symbolic world, on the program track: it finds its target by the program's words alone (the loop
    gives it the program without recorded outputs), and attempts nothing it cannot do."""
    from muble_plugins.common.episodes import run_symbolic_episode

    solved = set()
    for name, ins, scene in symbolic_episodes:
        result = run_symbolic_episode(ins, scene, greedy_agent())
        if name in ("measure_weight_single", "pick_up_lightest"):
            assert result.outcome is Outcome.SUCCESS, (ins.instruction, [str(a) for a in result.actions])
            solved.add(name)
        else:
            assert result.actions == [], (ins.instruction, [str(a) for a in result.actions])
    assert solved == {"measure_weight_single", "pick_up_lightest"}


def test_greedy_does_nothing_on_the_language_track(greedy_agent, symbolic_episodes):
    from muble_plugins.common.success import check
    from muble_plugins.common.symbolic import SymbolicWorld

    name, ins, scene = next(e for e in symbolic_episodes if e[0] == "measure_weight_single")
    result = run_episode(ins, SymbolicWorld(scene), greedy_agent(), check, track="language")
    assert result.actions == [] and result.outcome is not Outcome.SUCCESS


def test_greedy_does_nothing_in_a_mode_it_is_told_gives_no_words(greedy_agent, symbolic_episodes):
    name, ins, scene = next(e for e in symbolic_episodes if e[0] == "measure_weight_single")
    agent, told = greedy_agent(), agent_instruction(ins)
    agent.reset(told, Observation(scene=scene), track=Track.program, mode=ObservationMode.masks)
    assert agent.act(told, Observation(scene=scene)) is None
    agent.reset(told, Observation(scene=scene), track=Track.program, mode=ObservationMode.graph)
    assert agent.act(told, Observation(scene=scene)).name == "move"


def test_greedy_stops_after_a_failed_primitive(greedy_agent, symbolic_episodes):
    name, ins, scene = next(e for e in symbolic_episodes if e[0] == "measure_weight_single")
    agent, told = greedy_agent(), agent_instruction(ins)
    agent.reset(told, Observation(scene=scene))
    first = agent.act(told, Observation(scene=scene))
    assert first.name == "move"
    failed = Observation(scene=scene, last_result=ActionResult(False, failure_reason="no collision-free path"),
                         step=1)
    assert agent.act(told, failed) is None
    assert agent.act(told, Observation(scene=scene, step=2)) is None  # and stays stopped


@pytest.mark.slow
def test_greedy_succeeds_under_muble_eval_on_a_generated_split(example_site, tmp_path):
    """The third-party agent under ``muble eval`` for real: generated measure_weight_single episodes, physics,
    the judge; it weighs each target once and answers with the grams it measured."""
    data = tmp_path / "data"
    generated = run(["generate", "dataset.splits=[val]", "dataset.sizes=[2]", "dataset.sequences=false",
                     f"dataset.root={data}", "dataset.templates=[measure_weight_single]", "dataset.workers=1",
                     f"hydra.run.dir={tmp_path / 'generate'}"], example_site, MUJOCO_GL="egl")
    assert generated.returncode == 0, generated.stderr[-3000:]
    out = tmp_path / "eval"
    evaluated = run(["eval", "agent=greedy", f"dataset.root={data}", "dataset.workers=1", f"hydra.run.dir={out}"],
                    example_site, MUJOCO_GL="egl")
    assert evaluated.returncode == 0, evaluated.stderr[-3000:]
    report = json.loads((out / "report.json").read_text())
    assert report["agent"] == "greedy" and report["track"] == "program" and report["mode"] == "graph"
    overall = report["splits"]["val"]["overall"]
    assert overall["episodes"] == 2 and overall["successes"] == 2, report["splits"]["val"]
    records = [json.loads(line) for line in (out / "episodes_val.jsonl").read_text().splitlines()]
    assert [r["outcome"] for r in records] == ["success", "success"]
    for r in records:
        assert r["template"] == "measure_weight_single" and r["measurements"] == 1
        assert [p.split("(")[0] for p in r["primitives"]] == ["move", "approach", "close_gripper", "lift", "weigh"]
        assert len(r["answer"]) == 1 and r["answer"][0] > 0
