"""``muble eval``: an agent over a generated split, with physics; the results table, report, plot and summary."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from PIL import Image

from muble.core.types import Outcome
from muble.evaluation.plot import success_bar_chart
from muble.evaluation.report import OVERALL, success_table, summarize

TEMPLATES = "[measure_weight_single,move_single]"
OUTCOMES = {o.value for o in Outcome}


def muble(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "HYDRA_FULL_ERROR": "0", "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    return subprocess.run([sys.executable, "-m", "muble.app.cli", *args], capture_output=True, text=True, env=env,
                          timeout=300)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """Three val scenes with instructions of two quick templates (no ground-truth sequences: eval runs them)."""
    root = tmp_path_factory.mktemp("eval") / "ds"
    result = muble("generate", "dataset.splits=[val]", "dataset.sizes=[3]", f"dataset.root={root}",
                   "dataset.sequences=false", "dataset.executor=serial", f"dataset.templates={TEMPLATES}",
                   "renderer.width=96", "renderer.height=64", f"hydra.run.dir={root.parent / 'gen'}")
    assert result.returncode == 0, result.stderr[-2000:]
    return root


def evaluate(dataset: Path, out: Path, *overrides: str) -> tuple[subprocess.CompletedProcess, list[dict], dict]:
    result = muble("eval", f"dataset.root={dataset}", f"hydra.run.dir={out}", *overrides)
    assert result.returncode == 0, result.stderr[-2000:]
    records = [json.loads(line) for line in (out / "episodes_val.jsonl").read_text().splitlines()]
    return result, records, json.loads((out / "report.json").read_text())


@pytest.fixture(scope="module")
def oracle_run(dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("oracle")
    return out, *evaluate(dataset, out, "agent=oracle", "dataset.executor=processes", "dataset.workers=2")


@pytest.mark.slow
def test_oracle_eval_writes_table_report_plot_and_summary(oracle_run):
    out, result, records, report = oracle_run
    assert [r["index"] for r in records] == [0, 1, 2]
    assert {r["template"] for r in records} <= {"measure_weight_single", "move_single"}
    for r in records:
        assert r["outcome"] in OUTCOMES
        assert r["ground_truth_primitives"] > 0 and r["primitives"], r
        assert r["timing"]["total"] >= r["timing"]["physics"] > 0 and r["timing"]["rendering"] == 0.0
    summary = report["splits"]["val"]
    overall = summary[OVERALL]
    # Every episode lands in exactly one class of the taxonomy, and the report agrees with the episode file.
    assert sum(overall["outcomes"].values()) == overall["episodes"] == 3
    assert set(overall["outcomes"]) == OUTCOMES
    assert overall["successes"] == sum(r["outcome"] == "success" for r in records)
    assert sum(s["episodes"] for s in summary["templates"].values()) == 3
    assert report["manifest"]["seeds"]["seed"] == 0 and report["manifest"]["versions"]["mujoco"]
    # The printed table has a row per task type and the overall row with the same rate.
    for template in summary["templates"]:
        assert template in result.stdout
    overall_row = next(line for line in result.stdout.splitlines() if line.startswith(OVERALL))
    assert overall_row.split()[1:] == ["3", str(overall["successes"]), f"{100 * overall['success_rate']:.1f}%"]
    with Image.open(out / "success_val.png") as img:
        assert img.size[0] >= 200 and img.size[1] >= 200
    md = (out / "summary.md").read_text()
    assert "| **overall** | **3** |" in md and "success_val.png" in md and "execution_error" in md


@pytest.mark.slow
def test_eval_results_do_not_depend_on_executor(dataset, oracle_run, tmp_path):
    _, _, parallel, _ = oracle_run
    _, serial, _ = evaluate(dataset, tmp_path, "agent=oracle", "dataset.executor=serial")
    strip = lambda rs: [{k: v for k, v in r.items() if k != "timing"} for r in rs]  # noqa: E731
    assert strip(serial) == strip(parallel)


@pytest.mark.slow
def test_random_agent_does_not_beat_the_oracle(dataset, oracle_run, tmp_path):
    _, _, _, oracle = oracle_run
    _, records, report = evaluate(dataset, tmp_path, "agent=random", "agent.stop_probability=0.2",
                                  "episode.max_steps=6", "dataset.executor=serial")
    assert len(records) == 3 and all(r["outcome"] in OUTCOMES for r in records)
    assert report["splits"]["val"][OVERALL]["success_rate"] <= oracle["splits"]["val"][OVERALL]["success_rate"]


@pytest.mark.parametrize("overrides, message", [
    (["agent=oracle", "dataset.root={missing}"], "does not exist; set dataset.root="),
    (["agent.name=teleporter", "dataset.root={root}"], "set agent= to one of: oracle, random"),
    (["agent=oracle", "dataset.root={root}", "dataset.splits=[test]"], "splits present: val"),
])
def test_bad_input_says_what_to_change(tmp_path, overrides, message):
    root = tmp_path / "ds"
    (root / "val" / "instructions").mkdir(parents=True)
    (root / "val" / "scenes").mkdir()
    args = [a.format(missing=tmp_path / "nowhere", root=root) for a in overrides]
    result = muble("eval", *args, f"hydra.run.dir={tmp_path / 'out'}")
    assert result.returncode != 0
    assert message in result.stderr


def test_summary_counts_every_class_and_orders_rows_by_the_template_mix():
    records = [{"index": 2, "template": "move_single", "outcome": "success", "primitives": ["a"] * 6, "timing": None},
               {"index": 0, "template": "stack_three", "outcome": "loop_detected", "primitives": ["a"] * 4,
                "timing": {"physics": 3.0, "planning": 1.0, "rendering": 0.0, "total": 4.0}},
               {"index": 1, "template": "move_single", "outcome": "timeout", "primitives": [], "timing": None}]
    summary = summarize(records, ["stack_three", "measure_weight_single", "move_single"])
    assert list(summary["templates"]) == ["stack_three", "move_single"]
    assert summary["templates"]["move_single"]["success_rate"] == 0.5
    assert summary[OVERALL]["successes"] == 1 and summary["failures"]["loop_detected"] == 1
    assert summary["failures"]["timeout"] == 1 and summary["failures"]["broken_scene"] == 0
    assert summary["timing"]["episodes_per_hour_per_worker"] == pytest.approx(900.0)
    table = success_table(summary)
    assert table.splitlines()[-1].split() == [OVERALL, "3", "1", "33.3%"]
    png = success_bar_chart({"move_single": 0.5, OVERALL: 1 / 3}, "t")
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
