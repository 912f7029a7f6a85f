"""Closed-loop metrics from hand-written records: recovery per disturbance kind, detection delay (with an event
never addressed), extra primitives and fired against planned, in the summary, its tables, the results file,
``muble compare`` and the site; records without disturbances give the report they always gave."""
from __future__ import annotations

import copy
import json
import re

import pytest

from muble.evaluation.closed_loop import detection_delay, parse_action
from muble.evaluation.compare import compare, labelled, markdown as compare_markdown, text as compare_text
from muble.evaluation.report import OVERALL, markdown, success_table, summarize
from muble.evaluation.results import results_document
from muble.evaluation.site import build_site
from muble.evaluation.stats import wilson

MOVE, WEIGH = "move_single", "measure_weight_single"
MANIFEST = {"versions": {"muble": "0.1.0", "mujoco": "3.17.0"}, "python": "3.13.0", "git_revision": "abc123"}
RUN = {"protocol": None, "protocol_split": None, "data_sha256": "d" * 64, "agent": "oracle",
       "agent_config": {"name": "oracle"}, "track": "program", "mode": "graph", "seed": 0, "dataset": "/nowhere"}


def _event(kind: str, step: int, obj: int | None, **extra) -> dict:
    return {"kind": kind, "step": step, "trigger": f"{kind} trigger", "object": obj, "force": None, "impulse": None,
            "duration": 0.0, "detail": {}, **extra}


def _record(index: int, template: str, outcome: str, primitives: list[str], gt: int, events: list[dict],
            planned: int) -> dict:
    return {"index": index, "template": template, "outcome": outcome, "primitives": primitives,
            "steps": [{"action": p, "success": True, "measurement": None, "failure_reason": None, "held": None}
                      for p in primitives],
            "ground_truth_primitives": gt, "measurements": 0, "ground_truth_measurements": 0, "timing": None,
            "instruction": f"instruction {index}", "keyframes": [], "disturbances": events,
            "disturbances_planned": planned}


def _records() -> list[dict]:
    return [
        # A slip during the lift (step 3) of object 3; the very next primitive goes back to it: delay 0. Solved in
        # 7 primitives against a plan of 5: 2 extra.
        _record(0, MOVE, "success", ["approach(target=3)", "grasp()", "lift()", "approach(target=3)", "grasp()",
                                     "lift()", "move(target=2)"], 5, [_event("slip", 3, 3)], 1),
        # A reading that failed (weigh, step 4) is measured again after one other primitive: delay 1. A bump of
        # object 5 after the last primitive (step 7) is never addressed. Solved in 7 against 6: 1 extra.
        _record(1, WEIGH, "success", ["approach(target=4)", "grasp()", "lift()", "weigh()", "lower(target='front')",
                                      "weigh()", "release()"], 6,
                [_event("sensor_dropout", 4, 4, detail={"primitive": "weigh"}),
                 _event("bump", 7, 5, force=[1.5, -0.5, 0.0], impulse=[0.3, -0.1, 0.0], duration=0.4,
                        detail={"from": [0.1, 0.2], "to": [0.15, 0.25]})], 2),
        # A bump of object 2 after step 1, addressed by the fourth primitive (a target written as a string): delay
        # 2. Not solved: no extra primitives counted.
        _record(2, MOVE, "timeout", ["lower(target='front')", "approach(target=1)", "grasp()", "approach(target='2')"],
                4, [_event("bump", 1, 2)], 2),
        # Planned, but nothing fired: not disturbed, its plan still counts.
        _record(3, MOVE, "success", ["approach(target=1)"], 1, [], 1),
    ]


def _without_disturbances(records: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in ("disturbances", "disturbances_planned")} for r in records]


def _share(successes: int, episodes: int) -> dict:
    low, high = wilson(successes, episodes)
    return {"episodes": episodes, "successes": successes, "rate": pytest.approx(successes / episodes),
            "ci_low": pytest.approx(low), "ci_high": pytest.approx(high)}


def test_detection_delay_counts_the_primitives_between_the_disturbed_one_and_the_one_that_addresses_it():
    primitives = ["approach(target=3)", "grasp()", "lift()", "approach(target=3)"]
    assert detection_delay(_event("slip", 3, 3), primitives, {"weigh"}) == 0
    assert detection_delay(_event("slip", 1, 3), primitives, {"weigh"}) == 2  # the slipped-in grasp and lift
    assert detection_delay(_event("slip", 3, 7), primitives, {"weigh"}) is None  # object 7 never named
    assert detection_delay(_event("topple", 2, None), primitives, {"weigh"}) is None  # nothing to address
    assert detection_delay(_event("sensor_dropout", 1, 3), ["weigh()", "lift()", "weigh()"], {"weigh"}) == 1
    assert parse_action("lower(target='front', speed=0.1)") == ("lower", {"target": "'front'", "speed": "0.1"})


def test_the_summary_has_recovery_per_kind_detection_delay_extra_primitives_and_fired_over_planned():
    summary = summarize(_records(), [MOVE, WEIGH])
    loop = summary[OVERALL]["closed_loop"]
    assert loop == {"disturbed": 3, "recovered": 2, "recovery_rate": pytest.approx(2 / 3),
                    "ci_low": pytest.approx(wilson(2, 3)[0]), "ci_high": pytest.approx(wilson(2, 3)[1]),
                    "recovery_by_kind": {"bump": _share(1, 2), "sensor_dropout": _share(1, 1), "slip": _share(1, 1)},
                    "disturbances_fired": 4, "disturbances_planned": 6,
                    "detection_delay": pytest.approx(1.0), "addressed": 3, "unaddressed": 1,  # (0 + 1 + 2) / 3
                    "extra_primitives": pytest.approx(1.5), "extra_primitives_episodes": 2}  # (2 + 1) / 2
    move = summary["templates"][MOVE]["closed_loop"]
    counts = ("disturbed", "recovered", "disturbances_fired", "disturbances_planned")
    assert [move[k] for k in counts] == [2, 1, 2, 4]
    assert (move["detection_delay"], move["unaddressed"], move["extra_primitives"]) == (1.0, 0, 2.0)
    assert move["recovery_by_kind"] == {"bump": _share(0, 1), "slip": _share(1, 1)}
    weigh = summary["templates"][WEIGH]["closed_loop"]
    assert (weigh["disturbed"], weigh["detection_delay"], weigh["unaddressed"], weigh["extra_primitives"]) == (
        1, 1.0, 1, 1.0)
    # The rest of the summary is what the same records give without disturbances.
    plain = summarize(_without_disturbances(_records()), [MOVE, WEIGH])
    stripped = copy.deepcopy(summary)
    for row in [*stripped["templates"].values(), stripped[OVERALL]]:
        del row["closed_loop"]
    assert stripped == plain


def test_the_tables_add_the_closed_loop_after_the_unchanged_success_table():
    summary = summarize(_records(), [MOVE, WEIGH])
    plain = success_table(summarize(_without_disturbances(_records()), [MOVE, WEIGH]), "title")
    table = success_table(summary, "title")
    assert table.startswith(plain + "\n\nclosed loop (")
    rows = {line.split()[0]: line.split() for line in table[len(plain):].splitlines() if line.strip()}
    assert rows[OVERALL] == [OVERALL, "3", "2", "66.7%", "[20.8%,", "93.9%]", "4/6", "1.00", "1", "1.50"]
    assert rows[MOVE] == [MOVE, "2", "1", "50.0%", "[9.5%,", "90.5%]", "2/4", "1.00", "0", "2.00"]
    assert rows["bump"] == ["bump", "2", "1", "50.0%", "[9.5%,", "90.5%]"]
    assert rows["slip"][:4] == ["slip", "1", "1", "100.0%"]

    md = markdown({"agent": "oracle", "dataset": "/data", "splits": {"val": summary}}, {})
    assert ("| **overall** | **3** | **2** | **66.7%** | **[20.8%, 93.9%]** | **4/6** | **1.00** | **1** | **1.50** |"
            in md)
    assert "| sensor_dropout | 1 | 1 | 100.0% | [20.7%, 100.0%] |" in md and "Closed loop: disturbed:" in md


def test_records_without_disturbances_give_the_old_summary_tables_and_files(tmp_path):
    records = _without_disturbances(_records())
    summary = summarize(records, [MOVE, WEIGH])
    assert set(summary) == {"templates", OVERALL, "failures", "mean_primitives", "timing", "bad_entries",
                            "agent_stats"}
    for row in [*summary["templates"].values(), summary[OVERALL]]:
        assert set(row) == {"episodes", "successes", "success_rate", "ci_low", "ci_high", "spl", "measurement_ratio",
                            "outcomes"}
    table = success_table(summary)
    assert "closed loop" not in table and table.splitlines()[-1].startswith(OVERALL)
    md = markdown({"agent": "oracle", "dataset": "/data", "splits": {"val": summary}}, {})
    assert "Closed loop" not in md and "disturb" not in md
    doc = results_document(run=RUN, manifest=MANIFEST, splits={"val": (summary, records)})
    assert set(doc["splits"]["val"]["summary"][OVERALL]) == {"episodes", "successes", "rate", "ci", "spl",
                                                            "measurement_ratio"}
    assert set(doc["splits"]["val"]["episodes"][0]) == {"index", "template", "outcome", "primitives_used",
                                                       "ground_truth_primitives", "measurements",
                                                       "ground_truth_measurements"}
    comparison = compare(labelled([tmp_path / "a"], [doc]))
    assert "recovery" not in comparison and "recovery" not in compare_text(comparison)


def _run_folder(root, name: str, records: list[dict]):
    folder = root / name
    folder.mkdir()
    summary = summarize(records, [MOVE, WEIGH])
    doc = results_document(run={**RUN, "agent": name}, manifest=MANIFEST, splits={"val": (summary, records)})
    (folder / "results.json").write_text(json.dumps(doc))
    (folder / "episodes_val.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    return folder, doc


def test_results_and_compare_show_the_recovery_rate_with_n(tmp_path):
    folder, doc = _run_folder(tmp_path, "closed", _records())
    assert doc["splits"]["val"]["summary"][OVERALL]["closed_loop"]["recovered"] == 2
    assert [e["disturbance_kinds"] for e in doc["splits"]["val"]["episodes"]] == [
        ["slip"], ["sensor_dropout", "bump"], ["bump"], []]
    assert [e["disturbances_planned"] for e in doc["splits"]["val"]["episodes"]] == [1, 2, 2, 1]
    _, plain = _run_folder(tmp_path, "open", _without_disturbances(_records()))
    comparison = compare(labelled([folder, tmp_path / "open"], [doc, plain]))
    assert comparison["recovery"]["open"] is None
    assert comparison["recovery"]["closed"][OVERALL] == {"episodes": 3, "successes": 2, "rate": pytest.approx(2 / 3),
                                                         "ci": pytest.approx(list(wilson(2, 3)))}
    assert comparison["recovery"]["closed"]["bump"]["episodes"] == 2
    printed = compare_text(comparison)
    assert "recovery rate after disturbances" in printed
    overall = [line for line in printed.splitlines() if line.startswith(OVERALL)]
    assert overall[1].split() == [OVERALL, "66.7%", "[20.8%,", "93.9%]", "n=3", "-"]  # after the success table
    md = compare_markdown(comparison)
    assert "## Recovery after disturbances" in md and "| **overall** | **66.7% [20.8%, 93.9%] n=3** | **-** |" in md


def test_the_site_shows_the_recovery_rate_and_each_disturbance_on_its_episode_page(tmp_path):
    from PIL import Image

    records = _records()
    # Episode 0 has a keyframe before its first primitive and after each of its 7: the slip (step 3) lies between
    # keyframes 2 and 3.
    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(len(records[0]["primitives"]) + 1):
        Image.new("RGB", (8, 8), (30 * i, 0, 0)).save(frames / f"frame_{i:04d}.png")
    records[0]["keyframes"] = [str(p) for p in sorted(frames.iterdir())]
    closed, _ = _run_folder(tmp_path, "closed", records)
    built = build_site([closed], tmp_path / "site")
    assert built == {"runs": 1, "episodes": 4}
    board = (tmp_path / "site" / "index.html").read_text()
    assert ">recovery</th>" in board and "2/3 (66.7%)" in board and "[20.8%, 93.9%]" in board
    run = (tmp_path / "site" / "runs" / "closed" / "val" / "index.html").read_text()
    assert "Closed loop" in run and "sensor_dropout" in run
    page = (tmp_path / "site" / "runs" / "closed" / "val" / "000001.html").read_text()
    assert "<h2>Disturbances</h2>" in page and "2 fired of 2 planned" in page
    assert '<a href="#step-4">step 4</a>' in page and "<b>sensor_dropout</b>" in page
    assert "<code>weigh()</code>" in page and "<td>1 primitive</td>" in page
    assert "<b>bump</b>" in page and '<a href="#step-7">step 7</a>' in page and "never addressed" in page
    assert "1.5, -0.5, 0.0" in page and "from: [0.1, 0.2]" in page
    assert '<tr id="step-4" class="disturbed">' in page
    slipped = (tmp_path / "site" / "runs" / "closed" / "val" / "000000.html").read_text()
    assert re.search(r'<img src="[^"]+/0002\.png" alt="keyframe before step 3"', slipped)
    assert re.search(r'<img src="[^"]+/0003\.png" alt="keyframe after step 3"', slipped)
    assert re.search(r'<figure class="disturbed"><img src="[^"]+/0003\.png"', slipped)
    assert "<td>0 primitives</td>" in slipped and "<code>lift()</code>" in slipped
    # A run without disturbances: no recovery column, no disturbance section.
    (tmp_path / "plain").mkdir()
    plain, _ = _run_folder(tmp_path / "plain", "open", _without_disturbances(_records()))
    build_site([plain], tmp_path / "plain_site")
    assert "recovery" not in (tmp_path / "plain_site" / "index.html").read_text()
    assert "Disturbances" not in (tmp_path / "plain_site" / "runs" / "open" / "val" / "000001.html").read_text()
