"""The learned planner's trainer takes a package's hidden property from the registry: with the example package
installed, the planner's classes hold its measuring primitive (``feel``), and a planner trained on the package's two
temperature templates alone solves their symbolic episodes on scenes it never saw."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("torch")

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "docs" / "examples" / "muble-example-plugin" / "muble_example_plugin"

# Run in a process of its own: the planner's classes and features are those of the properties registered when its
# module is first imported, as in a process where the package is installed.
SCRIPT = """
import json, sys
from pathlib import Path
import torch
torch.set_num_threads(1)
from muble import Outcome
from muble.core.training import TrainingRun
from muble_plugins.common.episodes import run_symbolic_episode
from muble_plugins.learned.agent import LearnedPlannerAgent
from muble_plugins.learned.planner import PlannerTrainer, instructions_for, scene_for
from muble_plugins.learned.planner_features import CLASSES
templates = ("measure_temperature_single", "pick_up_temperature")
out = Path(sys.argv[1])
run = TrainingRun(out_dir=out, seed=1, resume=False, record={"config": {"train": {}}}, progress=False, threads=1)
PlannerTrainer(scenes=80, epochs=8, validation_scenes=0, batch_size=64, templates=list(templates)).train(run)
agent = LearnedPlannerAgent(checkpoint=str(out / "planner.pt"))
outcomes, felt = [], 0
for index in range(8):  # validation scenes: another stream than the training ones
    scene = scene_for(1, index, True)
    for instruction in instructions_for(scene, 1, index, True, templates):
        result = run_symbolic_episode(instruction, scene, agent)
        outcomes.append((instruction.template_id, result.outcome is Outcome.SUCCESS))
        felt += sum(step.action.name == "feel" for step in result.steps)
print(json.dumps({"classes": list(CLASSES), "outcomes": outcomes, "felt": felt}))
"""


def test_a_planner_trained_on_a_package_property_measures_it_and_solves_its_episodes(tmp_path, fake_distribution):
    modules = {f"muble_example_plugin.{m.stem}": m.read_text() for m in PACKAGE.glob("*.py")}
    site = fake_distribution("muble-example-plugin", {"example_contacts": "muble_example_plugin"}, modules)
    shutil.copy(PACKAGE / "temperature_templates.yaml", site / "muble_example_plugin")
    shutil.copytree(PACKAGE / "conf", site / "muble_example_plugin" / "conf", dirs_exist_ok=True)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(ROOT)])}
    done = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path / "run")], capture_output=True, text=True,
                          env=env, cwd=ROOT, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    found = json.loads(done.stdout.strip().splitlines()[-1])
    assert found["classes"][-2:] == ["feel", "stop"]  # after MuBlE's own primitives, before stop
    outcomes = found["outcomes"]
    assert {t for t, _ in outcomes} == {"measure_temperature_single", "pick_up_temperature"}
    assert len(outcomes) >= 10 and all(ok for _, ok in outcomes), outcomes
    assert found["felt"] >= len(outcomes)  # every episode measured what it needed by feeling it
