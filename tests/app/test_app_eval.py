"""``muble eval``: an agent over a generated split, with physics; the results table, report, plot and summary."""
from __future__ import annotations

import json
import os
import shutil
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
    assert overall_row.split()[1:4] == ["3", str(overall["successes"]), f"{100 * overall['success_rate']:.1f}%"]
    assert f"[{100 * overall['ci_low']:.1f}%, {100 * overall['ci_high']:.1f}%]" in overall_row
    results = json.loads((out / "results.json").read_text())
    assert (results["format"], results["version"], results["agent"]) == ("muble-results", 1, "oracle")
    assert [e["index"] for e in results["splits"]["val"]["episodes"]] == [0, 1, 2]
    with Image.open(out / "success_val.png") as img:
        assert img.size[0] >= 200 and img.size[1] >= 200
    md = (out / "summary.md").read_text()
    assert "| **overall** | **3** |" in md and "success_val.png" in md and "execution_error" in md


def _stem(index: int) -> str:
    return f"SHOP_VRB2_val_{index:06d}"


def _scene(index: int) -> str:
    return f"val/scenes/{_stem(index)}.json"


def _instruction(index: int) -> str:
    return f"val/instructions/{_stem(index)}.json"


def _write_json(path: Path, data) -> None:
    path.write_text(json.dumps(data))  # allow_nan: Python writes NaN as the bare word, which is not JSON


def _edited(path: Path, change) -> dict:
    data = json.loads(path.read_text())
    change(data)
    return data


# Bad entries, each a copy of the good index 1 spoilt one way: index -> (the file at fault, what the error says).
BAD = {
    3: (_scene(3), "truncated"),
    4: (_scene(4), "not UTF-8"),
    5: (_instruction(5), "UTF-16"),
    6: (_scene(6), "3d_coords"),
    7: (_scene(7), "NaN"),
    8: (_scene(8), "no_such_model"),
    9: (_instruction(9), "no_such_template"),
    10: (_instruction(10), "program"),
    11: (_scene(11), "missing"),
    12: (_instruction(12), "missing"),
    13: (_scene(13), "inertia"),  # a mass MuJoCo's compiler (or the model check before it) refuses
    15: (_instruction(15), "expected a JSON object"),
    17: (_instruction(17), "truncated"),
}
NO_STIFFNESS = 14  # loads: a missing stiffness takes the object set's default for the object's material
SKIPPED = 16  # its instruction file says no template applied: not an episode
GOOD = 1


@pytest.fixture(scope="module")
def bad_dataset(dataset, tmp_path_factory) -> Path:
    """The generated split reduced to its index 1, plus entries spoilt in every way files get spoilt; the manifest
    lists them all, as if `muble generate` had written them (then two files went missing)."""
    from muble.app.generate import checksums

    root = tmp_path_factory.mktemp("bad") / "ds"
    shutil.copytree(dataset, root)
    for index in (0, 2):
        for rel in (_scene(index), _instruction(index), f"val/images/{_stem(index)}.png"):
            (root / rel).unlink()
    scene, instruction = root / _scene(GOOD), root / _instruction(GOOD)
    for index in [*BAD, NO_STIFFNESS, SKIPPED]:
        def renumber(d, index=index):
            d.update(image_index=index, image_filename=f"{_stem(index)}.png")
        _write_json(root / _scene(index), _edited(scene, renumber))
        _write_json(root / _instruction(index), _edited(instruction, renumber))
    text = scene.read_text()
    (root / _scene(3)).write_text(text[:len(text) // 2])
    (root / _scene(4)).write_bytes((root / f"val/images/{_stem(GOOD)}.png").read_bytes())
    (root / _instruction(5)).write_bytes(instruction.read_text().encode("utf-16"))
    _write_json(root / _scene(6), _edited(scene, lambda d: d["objects"][0].update({"3d_coords": "on the table"})))
    _write_json(root / _scene(7), _edited(scene, lambda d: d["objects"][0].update(weight_gt=float("nan"))))
    _write_json(root / _scene(8), _edited(scene, lambda d: d["objects"][0].update(file="no_such_model")))
    _write_json(root / _instruction(9), _edited(instruction, lambda d: d.update(template_id="no_such_template")))
    _write_json(root / _instruction(10), _edited(instruction, lambda d: d.pop("program")))
    _write_json(root / _scene(13), _edited(scene, lambda d: d["objects"][0].update(weight_gt=1e-9)))
    _write_json(root / _scene(NO_STIFFNESS), _edited(scene, lambda d: [o.pop("stiffness", None) for o in d["objects"]]))
    _write_json(root / _instruction(15), [instruction.read_text()])
    _write_json(root / _instruction(SKIPPED), {"split": "val", "image_index": SKIPPED, "instruction": None,
                                               "skipped": "no template of the mix applies to this scene"})
    (root / _instruction(17)).write_text("")
    manifest = json.loads((root / "manifest.json").read_text())
    manifest["files"] = checksums(root)
    (root / "manifest.json").write_text(json.dumps(manifest))
    (root / _scene(11)).unlink()
    (root / _instruction(12)).unlink()
    return root


@pytest.fixture(scope="module")
def bad_run(bad_dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("bad_eval")
    return out, *evaluate(bad_dataset, out, "agent=oracle", "dataset.executor=serial")


@pytest.mark.slow
def test_every_entry_gets_an_outcome_and_bad_ones_are_listed_by_file(bad_run, oracle_run):
    out, result, records, report = bad_run
    by_index = {r["index"]: r for r in records}
    # Every index the manifest lists is an episode, missing files included; the skipped one is not.
    assert sorted(by_index) == sorted([GOOD, NO_STIFFNESS, *BAD])
    summary = report["splits"]["val"]
    assert summary["skipped"] == [SKIPPED] and summary["indices_from"] == "manifest"
    listed = {e["file"]: e for e in summary["bad_entries"]}
    md = (out / "summary.md").read_text()
    for index, (file, says) in BAD.items():
        r = by_index[index]
        assert (r["outcome"], r["file"]) == ("invalid_data", file), r
        assert says in r["error"], r["error"]
        assert r["primitives"] == [] and r["timing"] is None
        assert listed[file]["outcome"] == "invalid_data" and listed[file]["error"] == r["error"]
        assert file in result.stdout and file in md
    assert len(summary["bad_entries"]) == len(BAD)
    # The template is known where the instruction file could be read; the others have their own row.
    unknown = {i for i, r in by_index.items() if r["template"] == "unknown"}
    assert unknown == {5, 9, 10, 12, 15, 17}
    assert all(by_index[i]["template"] == by_index[GOOD]["template"] for i in set(BAD) - unknown)
    # Bad entries count in the denominators: per template and overall.
    assert summary[OVERALL]["episodes"] == len(records) and summary[OVERALL]["outcomes"]["invalid_data"] == len(BAD)
    assert summary["templates"]["unknown"]["episodes"] == len(unknown)
    assert summary["templates"][by_index[GOOD]["template"]]["episodes"] == len(records) - len(unknown)
    assert list(summary["templates"])[-1] == "unknown"
    # A scene without stiffness runs with the material default.
    assert by_index[NO_STIFFNESS]["outcome"] not in ("invalid_data", "broken_scene"), by_index[NO_STIFFNESS]
    assert by_index[NO_STIFFNESS]["primitives"]
    # The good entry is scored exactly as in the clean dataset.
    _, _, clean, _ = oracle_run
    strip = lambda r: {k: v for k, v in r.items() if k != "timing"}  # noqa: E731
    assert strip(by_index[GOOD]) == strip(next(r for r in clean if r["index"] == GOOD))


@pytest.mark.slow
def test_eval_resumes_from_the_records_of_an_interrupted_run(bad_dataset, bad_run, tmp_path):
    first_out, _, first, first_report = bad_run
    out = tmp_path / "resumed"
    shutil.copytree(first_out, out)
    (out / "report.json").unlink()
    # As if killed while writing index 13's line: complete lines for the episodes finished before (marked, to tell
    # whether they ran again; both with physics among them), a partial line last; the others were not reached.
    finished = (GOOD, 3, 4, 5, NO_STIFFNESS)
    kept = [r for r in first if r["index"] in finished]
    cut = json.dumps(next(r for r in first if r["index"] == 13), sort_keys=True)[:60]
    (out / "episodes_val.jsonl").write_text(
        "".join(json.dumps({**r, "marker": "kept"}, sort_keys=True) + "\n" for r in kept) + cut)
    result, records, report = evaluate(bad_dataset, out, "agent=oracle", "dataset.executor=serial")
    assert [r["index"] for r in records] == [r["index"] for r in first]
    for r, before in zip(records, first):
        # The kept ones (the good episode among them) were read back, not run again; the others ran.
        assert (r.get("marker") == "kept") == (r["index"] in finished), r
        assert (r["outcome"], r["file"], r["error"]) == (before["outcome"], before["file"], before["error"])
    log = (out / "hydra_app.log").read_text()
    assert "5 of 15 episodes already done" in log and "incomplete or not JSON" in log
    assert report["splits"]["val"][OVERALL] == first_report["splits"]["val"][OVERALL]
    assert report["splits"]["val"]["bad_entries"] == first_report["splits"]["val"]["bad_entries"]
    # Resuming with other settings is refused, naming what differs.
    refused = muble("eval", f"dataset.root={bad_dataset}", f"hydra.run.dir={out}", "agent=random",
                    "dataset.executor=serial")
    assert refused.returncode == 2
    assert "agent.name: 'oracle' -> 'random'" in refused.stderr and "another folder" in refused.stderr


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
    (["agent.name=teleporter", "dataset.root={root}"], "set agent= to one of: learned_planner, llm, oracle, random"),
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
    assert table.splitlines()[-1].split() == [OVERALL, "3", "1", "33.3%", "[6.1%,", "79.2%]", "-", "-"]
    png = success_bar_chart({"move_single": 0.5, OVERALL: 1 / 3}, "t")
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
