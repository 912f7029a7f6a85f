"""Scores with their uncertainty: Wilson intervals and the exact McNemar test, the report's intervals and efficiency,
the results file, and ``muble compare`` end to end on results files written by hand."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from muble.app.cli import main as muble_main
from muble.core.errors import ConfigError
from muble.evaluation.compare import compare, labelled
from muble.evaluation.episodes import ground_truth_counts, measuring_primitives
from muble.evaluation.report import OVERALL, markdown, success_table, summarize
from muble.evaluation.results import FORMAT, VERSION, read_results, results_document
from muble.evaluation.stats import mcnemar_exact, wilson

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


# --- the statistics ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("successes, n, low, high", [
    (8, 10, 0.4902, 0.9433),
    (0, 10, 0.0, 0.2775),
    (10, 10, 0.7225, 1.0),
    (1, 3, 0.0615, 0.7923),
    (50, 100, 0.4038, 0.5962),
])
def test_wilson_interval_known_values(successes, n, low, high):
    got = wilson(successes, n)
    assert got == (pytest.approx(low, abs=5e-5), pytest.approx(high, abs=5e-5))


def test_wilson_without_episodes_knows_nothing_and_rejects_impossible_counts():
    assert wilson(0, 0) == (0.0, 1.0)
    with pytest.raises(ValueError):
        wilson(3, 2)


def test_wilson_narrows_with_n_and_other_z():
    wide, narrow = wilson(3, 4), wilson(75, 100)
    assert wide[0] < narrow[0] < 0.75 < narrow[1] < wide[1]
    z99 = wilson(75, 100, z=2.575829)
    assert z99[0] < narrow[0] and z99[1] > narrow[1]


@pytest.mark.parametrize("b, c, p", [(0, 5, 0.0625), (5, 0, 0.0625), (1, 9, 0.021484375), (3, 3, 1.0),
                                     (0, 0, 1.0), (0, 1, 1.0), (10, 0, 2 / 1024)])
def test_mcnemar_exact_known_values(b, c, p):
    assert mcnemar_exact(b, c) == pytest.approx(p, rel=1e-12)


def test_mcnemar_exact_matches_scipys_binomial_test():
    from scipy.stats import binomtest

    for b in range(0, 25, 3):
        for c in range(0, 25, 4):
            if b + c:
                assert mcnemar_exact(b, c) == pytest.approx(binomtest(b, b + c, 0.5).pvalue, rel=1e-9), (b, c)
    assert 0.0 < mcnemar_exact(3000, 2900) < 1.0  # exact integer arithmetic: no overflow at large counts


# --- the report -------------------------------------------------------------------------------------------------
def _record(index: int, template: str, outcome: str, used: int, gt: int, measured: int = 0, gt_measured: int = 0):
    return {"index": index, "template": template, "outcome": outcome, "primitives": ["move(target=1)"] * used,
            "ground_truth_primitives": gt, "measurements": measured, "ground_truth_measurements": gt_measured,
            "timing": None}


def test_summary_has_intervals_and_efficiency_per_template_and_overall():
    records = [_record(0, "move_single", "success", 6, 6),
               _record(1, "move_single", "success", 12, 6),
               _record(2, "move_single", "timeout", 30, 6),
               _record(3, "measure_weight_single", "success", 8, 8, measured=2, gt_measured=1),
               _record(4, "measure_weight_single", "incorrect_answer", 7, 8, measured=0, gt_measured=1)]
    summary = summarize(records, ["measure_weight_single", "move_single"])
    move = summary["templates"]["move_single"]
    assert (move["episodes"], move["successes"]) == (3, 2)
    assert (move["ci_low"], move["ci_high"]) == pytest.approx(wilson(2, 3))
    assert move["spl"] == pytest.approx((1 + 0.5 + 0) / 3)
    assert move["measurement_ratio"] is None  # no measurement was needed
    weigh = summary["templates"]["measure_weight_single"]
    assert weigh["spl"] == pytest.approx(0.5) and weigh["measurement_ratio"] == pytest.approx(1.0)
    o = summary[OVERALL]
    assert (o["ci_low"], o["ci_high"]) == pytest.approx(wilson(3, 5))
    assert o["spl"] == pytest.approx((1 + 0.5 + 0 + 1 + 0) / 5) and o["measurement_ratio"] == pytest.approx(1.0)

    table = success_table(summary, "agent oracle, split val; protocol none, track program, mode graph")
    lines = table.splitlines()
    assert lines[0].endswith("protocol none, track program, mode graph") and "95% CI" in lines[1]
    assert lines[-1].split() == [OVERALL, "5", "3", "60.0%", "[23.1%,", "88.2%]", "0.50", "1.00"]
    md = markdown({"agent": "oracle", "dataset": "/data", "protocol": "shopvrb2_v1", "track": "language",
                   "mode": "masks", "splits": {"val": summary}}, {})
    assert md.splitlines()[0] == "# Evaluation of agent `oracle` (protocol shopvrb2_v1, track language, mode masks)"
    assert "| move_single | 3 | 2 | 66.7% | [20.8%, 93.9%] | 0.50 | - |" in md


def test_records_without_a_plan_or_measurement_counts_leave_efficiency_open():
    old = [{"index": 0, "template": "move_single", "outcome": "success", "primitives": ["a"], "timing": None}]
    row = summarize(old)[OVERALL]
    assert row["spl"] is None and row["measurement_ratio"] is None
    assert success_table(summarize(old)).splitlines()[-1].split()[-2:] == ["-", "-"]


def test_measurements_are_counted_from_the_registry_in_either_spelling():
    assert {"weigh", "squeeze"} <= measuring_primitives() and "move" not in measuring_primitives()
    record = {"ground_truth_actions": [["approach_grasp", {"target": 1}], ["grasp", {}], ["pick_up", {}],
                                       ["weigh", {}], ["put_down", {}], ["release", {}], ["squeeze", {"target": 2}]]}
    assert ground_truth_counts(record) == {"ground_truth_primitives": 7, "ground_truth_measurements": 2}
    assert ground_truth_counts({}) == {"ground_truth_primitives": 0, "ground_truth_measurements": 0}


# --- the results file -------------------------------------------------------------------------------------------
MANIFEST = {"versions": {"muble": "0.1.0", "mujoco": "3.17.0"}, "python": "3.13.0", "git_revision": "abc123"}
RUN = {"protocol": None, "protocol_split": None, "data_sha256": "d" * 64, "agent": "oracle",
       "agent_config": {"name": "oracle"}, "track": "program", "mode": "graph", "seed": 0, "dataset": "/data"}


def test_results_document_has_the_documented_fields_and_reads_back(tmp_path):
    records = [_record(0, "move_single", "success", 6, 6), _record(1, "move_single", "timeout", 30, 6)]
    doc = results_document(run=RUN, manifest=MANIFEST, splits={"val": (summarize(records), records)})
    assert set(doc) == {"format", "version", "protocol", "protocol_split", "data_sha256", "agent", "agent_config",
                        "track", "mode", "seed", "dataset", "versions", "git", "splits"}
    assert (doc["format"], doc["version"], doc["git"]) == (FORMAT, VERSION, "abc123")
    move = doc["splits"]["val"]["summary"]["templates"]["move_single"]
    assert move == {"episodes": 2, "successes": 1, "rate": 0.5, "ci": list(wilson(1, 2)), "spl": 0.5,
                    "measurement_ratio": None}
    assert doc["splits"]["val"]["episodes"][1] == {"index": 1, "template": "move_single", "outcome": "timeout",
                                                   "primitives_used": 30, "ground_truth_primitives": 6,
                                                   "measurements": 0, "ground_truth_measurements": 0}
    (tmp_path / "results.json").write_text(json.dumps(doc))
    assert read_results(tmp_path) == doc


@pytest.mark.parametrize("content, says", [
    (None, "has no results.json"),
    ("{not json", "is not valid JSON"),
    (json.dumps({"format": "something-else", "version": 1, "splits": {}}), "is not a MuBlE results file"),
    (json.dumps({"format": FORMAT, "version": 2, "splits": {}}), "version 2 of the results format"),
    (json.dumps({"format": FORMAT, "version": 1, "splits": {"val": {"episodes": [{"index": "0"}]}}}),
     "episode 0 of split 'val'"),
])
def test_a_folder_without_a_readable_results_file_is_refused(tmp_path, content, says):
    if content is not None:
        (tmp_path / "results.json").write_text(content)
    with pytest.raises(ConfigError, match=says):
        read_results(tmp_path)


# --- muble compare ----------------------------------------------------------------------------------------------
TEMPLATES = ("move_single", "measure_weight_single")


def _results(successes: set[int], indices: range = range(20), split: str = "val", **run) -> dict:
    """A results file written by hand: episode i of template TEMPLATES[i % 2], a success where i is in
    ``successes``."""
    episodes = [{"index": i, "template": TEMPLATES[i % 2], "outcome": "success" if i in successes else "timeout",
                 "primitives_used": 6, "ground_truth_primitives": 6, "measurements": 0,
                 "ground_truth_measurements": 0} for i in indices]
    return {"format": FORMAT, "version": VERSION, **RUN, **run, "versions": MANIFEST["versions"], "git": "abc123",
            "splits": {split: {"summary": {"templates": {t: {} for t in TEMPLATES}, OVERALL: {}},
                               "episodes": episodes}}}


def _run_folder(root: Path, name: str, results: dict) -> Path:
    folder = root / name
    folder.mkdir()
    (folder / "results.json").write_text(json.dumps(results, indent=2))
    return folder


# Run A solves episodes 0-14, run B 0, 1 and 15-17: b = 13 (A only), c = 3 (B only).
A_SOLVES, B_SOLVES = set(range(15)), {0, 1, 15, 16, 17}


def test_compare_end_to_end(tmp_path, capsys):
    a = _run_folder(tmp_path, "oracle", _results(A_SOLVES))
    b = _run_folder(tmp_path, "random", _results(B_SOLVES, agent="random"))
    out = tmp_path / "cmp"
    assert muble_main(["compare", str(a), str(b), "--out", str(out)]) == 0
    printed = capsys.readouterr().out

    result = json.loads((out / "compare.json").read_text())
    assert result["templates"] == list(TEMPLATES)  # the order the runs' summaries give
    pair = result["pairs"][0]
    assert (pair["first"], pair["second"]) == ("oracle", "random")
    overall = pair[OVERALL]
    assert (overall["shared"], overall["b"], overall["c"]) == (20, 13, 3)
    by_hand = 2 * sum(math.comb(16, k) for k in range(4)) / 2 ** 16  # 2 * 697 / 65536
    assert overall["p_value"] == pytest.approx(by_hand, rel=1e-12) == mcnemar_exact(13, 3)
    # Per task type: even indices are move_single (A solves 8 of 10, B 0, 16), odd ones measure_weight_single.
    move = pair["templates"]["move_single"]
    assert (move["shared"], move["b"], move["c"], move["p_value"]) == (10, 7, 1, mcnemar_exact(7, 1))
    weigh = pair["templates"]["measure_weight_single"]
    assert (weigh["shared"], weigh["b"], weigh["c"], weigh["p_value"]) == (10, 6, 2, mcnemar_exact(6, 2))
    assert result["success"]["oracle"][OVERALL] == {"episodes": 20, "successes": 15, "rate": 0.75,
                                                    "ci": list(wilson(15, 20))}
    assert result["success"]["random"]["move_single"]["successes"] == 2 and result["warnings"] == []

    png = (out / "compare.png").read_bytes()
    assert png[:8] == PNG_MAGIC
    md = (out / "compare.md").read_text()
    assert "![success rate per task type with 95% intervals](compare.png)" in md
    assert "| **overall** | **20** | **13** | **3** | **0.0213** |" in md
    assert "75.0% [53.1%, 88.8%] n=20" in md and "25.0% [11.2%, 46.9%] n=20" in md
    assert "75.0% [53.1%, 88.8%] n=20" in printed and "exact McNemar p = 0.0213" in printed
    assert sorted(p.name for p in out.iterdir()) == ["compare.json", "compare.md", "compare.png"]


def test_compare_warns_when_runs_followed_different_settings(tmp_path, capsys):
    a = _run_folder(tmp_path, "a", _results(A_SOLVES))
    b = _run_folder(tmp_path, "b", _results(B_SOLVES, data_sha256="e" * 64, track="language"))
    assert muble_main(["compare", str(a), str(b), "--out", str(tmp_path / "cmp")]) == 0
    printed = capsys.readouterr().out
    assert "warning: the runs used different tracks (a: program, b: language)" in printed
    assert "warning: the runs used different data (dataset manifest sha256)" in printed
    assert "**Warnings:**" in (tmp_path / "cmp" / "compare.md").read_text()


def test_every_pair_of_three_runs_is_compared_on_the_episodes_they_share(tmp_path):
    runs = labelled([tmp_path / "x" / "run", tmp_path / "y" / "run", tmp_path / "z"],
                    [_results(A_SOLVES), _results(B_SOLVES, indices=range(10, 30)), _results(set())])
    assert [r.label for r in runs] == [str(tmp_path / "x" / "run"), str(tmp_path / "y" / "run"), "z"]
    pairs = compare(runs)["pairs"]
    assert [p[OVERALL]["shared"] for p in pairs] == [10, 20, 10]
    assert (pairs[0][OVERALL]["b"], pairs[0][OVERALL]["c"]) == (5, 3)  # indices 10-19: A 10-14, B 15-17


def test_runs_that_share_no_episode_are_refused(tmp_path, capsys):
    a = _run_folder(tmp_path, "a", _results(A_SOLVES))
    b = _run_folder(tmp_path, "b", _results(B_SOLVES, split="test"))
    out = tmp_path / "cmp"
    assert muble_main(["compare", str(a), str(b), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "share no episode" in err and "a has splits val, b has test" in err
    assert not out.exists()


def test_a_folder_that_is_no_eval_run_exits_2_and_writes_nothing(tmp_path):
    a = _run_folder(tmp_path, "a", _results(A_SOLVES))
    empty = tmp_path / "not_a_run"
    empty.mkdir()
    out = tmp_path / "cmp"
    env = {**os.environ, "HYDRA_FULL_ERROR": "0"}
    result = subprocess.run([sys.executable, "-m", "muble.app.cli", "compare", str(a), str(empty), "--out", str(out)],
                            capture_output=True, text=True, env=env, timeout=120)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith(f"muble compare: error: {empty} has no results.json")
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert not out.exists() and not any(p.name.startswith(".muble-tmp-") for p in tmp_path.iterdir())


# --- scripts/results_table.py -----------------------------------------------------------------------------------
def _results_table():
    import importlib.util

    path = Path(__file__).resolve().parents[2] / "scripts" / "results_table.py"
    spec = importlib.util.spec_from_file_location("results_table", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_results_table_counts_each_task_type_with_its_interval_beside_the_papers(tmp_path, capsys):
    a = _run_folder(tmp_path, "oracle", _results(A_SOLVES))
    b = _run_folder(tmp_path, "random", _results(B_SOLVES, agent="random"))
    out = tmp_path / "table.md"
    assert _results_table().main([f"oracle={a}", f"random={b}", "--out", str(out)]) == 0
    rows = {line.split(" | ")[0].strip("| `*"): line.split(" | ")[1:] for line in out.read_text().splitlines()}
    # Episodes 0-14 of 20: the even ones are move_single (8 of 10 solved), the odd ones measure_weight_single (7).
    assert rows["move_single"][0].startswith("80.0% [49–94] (8/10)")
    assert rows["measure_weight_single"][1].startswith("30.0% [11–60] (3/10)")  # B: the odd 1, 15 and 17
    assert rows["overall"][0].startswith("75.0% [53–89] (15/20)")
    assert rows["stack_weight"][-1].strip(" |") == "33%" and rows["overall"][-1].strip(" |") == "43.9%"
    assert capsys.readouterr().out == out.read_text()
    assert _results_table().main([f"oracle={a}", "--paper", "ycb", "--out", str(out)]) == 0
    rows = {line.split(" | ")[0].strip("| `*"): line.split(" | ")[1:] for line in out.read_text().splitlines()}
    assert rows["stack_weight"][-1].strip(" |") == "—" and rows["overall"][-1].strip(" |") == "76.7%"
    assert "YCB" in rows["task type"][-1]


def test_the_results_table_refuses_a_folder_without_results(tmp_path, capsys):
    assert _results_table().main([f"mine={tmp_path}"]) == 2
    assert "has no results.json" in capsys.readouterr().err
