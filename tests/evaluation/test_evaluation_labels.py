"""The site and ``muble compare`` never mislabel a number: a ``balance`` reading's true value in the reading's unit
(mm, not the scene file's metres) with its error, and a run limited to a split's first episodes
(``evaluation.limit``) labelled so in ``results.json``, on the leaderboard, on its run page and in ``muble compare``.
Run folders written here from records (no physics); ``tests/app/test_app_first_hour.py`` checks a real run."""
from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from muble.evaluation.compare import compare, labelled, text
from muble.evaluation.report import partial_split, summarize
from muble.evaluation.results import RESULTS_FILE, read_results, results_document
from muble.evaluation.site import build_site, reading_error
from muble.io.layout import DatasetLayout
from tests.core.test_core_data_files import SCENE

MANIFEST = {"versions": {"muble": "test"}, "python": "3", "git_revision": None}
COM_OFFSET_M = [0.0002, 0.0018]  # the scene file keeps metres
MEASURED_MM = [1.1, 2.6]


def _record(index: int, steps: list[dict] | None = None) -> dict:
    return {"split": "val", "index": index, "template": "measure_com_single", "task": "measure_com_offset",
            "instruction": "How far off-centre is the weight of the mug?", "outcome": "success",
            "primitives": [s["action"] for s in steps or []], "steps": steps or [], "measurements": 1,
            "ground_truth_primitives": 5, "ground_truth_measurements": 1, "answer": 2.8, "error": None,
            "timing": None, "keyframes": [], "file": None}


def write_run(folder: Path, dataset: Path, indices: list[int], listed: int) -> Path:
    """A ``muble eval`` output folder of ``indices`` of split ``val`` (of ``listed`` indices) on ``dataset``."""
    balance = [{"action": "lift()", "success": True, "measurement": None, "failure_reason": None, "held": 0},
               {"action": "balance()", "success": True, "measurement": MEASURED_MM, "failure_reason": None,
                "held": 0}]
    records = [_record(i, balance) for i in indices]
    summary = summarize(records, ["measure_com_single"])
    summary["partial"] = partial_split(len(records), listed)
    run = {"protocol": None, "protocol_split": None, "track": "program", "mode": "graph", "data_sha256": "d" * 64,
           "agent": "oracle", "agent_config": {"name": "oracle"}, "seed": 0, "dataset": str(dataset)}
    folder.mkdir(parents=True)
    (folder / RESULTS_FILE).write_text(json.dumps(results_document(run=run, manifest=MANIFEST,
                                                                   splits={"val": (summary, records)})))
    (folder / "episodes_val.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    return folder


@pytest.fixture()
def dataset(tmp_path) -> Path:
    """Scenes 0-3 of split val: a mug whose centre of mass sits [0.2, 1.8] mm off its centre."""
    scene = copy.deepcopy(SCENE)
    scene["objects"][0].update(id=0, com_offset=COM_OFFSET_M)
    layout = DatasetLayout(tmp_path / "ds", "val")
    for index in range(4):
        path = layout.split_dir / layout.scene(index)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(scene))
    return layout.root


def test_a_balance_row_shows_the_true_centre_of_mass_in_mm_with_its_error(tmp_path, dataset):
    run = write_run(tmp_path / "oracle", dataset, [0, 1, 2, 3], listed=4)
    build_site([run], tmp_path / "site")
    page = (tmp_path / "site" / "runs" / "oracle" / "val" / "000000.html").read_text()
    truth = page.split("Measured against true values")[1].split("</table>")[0]
    assert "<td>[1.1, 2.6] mm</td>" in truth
    assert "<td>[0.2, 1.8] mm</td>" in truth, truth  # the file's metres, shown in the reading's unit
    distance = ((1.1 - 0.2) ** 2 + (2.6 - 1.8) ** 2) ** 0.5
    assert f"<td>{distance:.3g} mm</td>" in truth and "0.0002" not in truth


def test_reading_errors_by_the_kind_of_reading():
    assert reading_error([1.1, 2.6], [0.2, 1.8], "mm")[1] == "1.2 mm"
    assert reading_error(101.0, 100.0, "g")[1] == "+1.0%"
    assert reading_error(True, True, "")[1] == "right" and reading_error(False, True, "")[1] == "wrong"
    assert reading_error(None, 3.0, "g") == (None, None)


def test_a_limited_run_is_labelled_first_n_everywhere(tmp_path, dataset):
    whole = write_run(tmp_path / "whole", dataset, [0, 1, 2, 3], listed=4)
    limited = write_run(tmp_path / "limited", dataset, [0, 1], listed=4)
    assert read_results(limited)["splits"]["val"]["partial"] == {"first": 2, "of": 4}
    assert "partial" not in read_results(whole)["splits"]["val"]
    build_site([whole, limited], tmp_path / "site")
    board = (tmp_path / "site" / "index.html").read_text()
    assert board.count("first 2 of 4 episodes") == 1
    assert "first 2 of 4 episodes" in (tmp_path / "site" / "runs" / "limited" / "val" / "index.html").read_text()
    assert "first" not in (tmp_path / "site" / "runs" / "whole" / "val" / "index.html").read_text().split("<h1>")[1] \
        .split("</h1>")[0]
    comparison = compare(labelled([whole, limited], [read_results(whole), read_results(limited)]))
    printed = text(comparison)
    assert "limited: agent oracle" in printed and "val: first 2 of 4 episodes" in printed
    assert any("share 2 episodes" in w and "different episodes" in w for w in comparison["warnings"])
