"""muble verify: an evaluation run's recorded decisions replayed with no agent, the world's fingerprint compared
after every primitive: a run replays to the unit on the machine that made it, a record made to differ is found at
the primitive where it differs, and bad input is named."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from muble.episode.fingerprint import difference, first_difference
from muble.evaluation.verify import action_of

MUBLE = [sys.executable, "-m", "muble.app.cli"]


def test_recorded_calls_read_back_as_the_calls_they_were():
    assert action_of("move(target=3)").params == {"target": 3}
    assert action_of("lower(target='front', attempt=2)").params == {"target": "front", "attempt": 2}
    assert action_of("weigh()").name == "weigh" and action_of("weigh()").params == {}


def test_fingerprints_differ_by_their_largest_unit_and_a_change_of_hand_is_a_difference():
    a = {"objects": {"0": [1, 2, 3, 0, 0, 0]}, "arm": [10, 20], "gripper": 400, "held": None}
    b = {"objects": {"0": [1, 2, 5, 0, 0, 0]}, "arm": [10, 21], "gripper": 400, "held": None}
    assert difference(a, b) == 2
    assert difference(a, {**a, "held": 0}) > 10**6
    assert first_difference([a, a, a], [a, b, b]) == (1, 2)
    assert first_difference([a, a, a], [a, b, b], tolerance=2) == (None, 2)
    assert first_difference([a, a], [a]) == (1, 0)  # a replay that ends early differs where it ends


@pytest.mark.slow
def test_a_run_replays_to_the_unit_and_a_record_made_to_differ_is_found(tmp_path):
    env = {**os.environ, "MUJOCO_GL": "egl", "MUBLE_DATA_CACHE": str(tmp_path / "cache")}
    run = tmp_path / "run"
    done = subprocess.run([*MUBLE, "eval", "protocol=shopvrb2_v2", "agent=oracle", "evaluation.limit=2",
                           "dataset.workers=1", f"hydra.run.dir={run}"], env=env, capture_output=True, text=True,
                          timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    path = run / "episodes_mini.jsonl"
    records = [json.loads(line) for line in path.read_text().splitlines()]
    assert all(len(r["fingerprints"]) == len(r["primitives"]) + 1 for r in records)
    assert all(r["platform"]["mujoco"] for r in records)
    same = subprocess.run([*MUBLE, "verify", str(run), "--workers", "1", "--out", str(tmp_path / "v.json")],
                          env=env, capture_output=True, text=True, timeout=900)
    assert same.returncode == 0, same.stdout + same.stderr[-2000:]
    report = json.loads((tmp_path / "v.json").read_text())["splits"]["mini"]
    assert report["identical"] == report["episodes"] == 2 and report["largest_difference"] == 0
    # The record of episode 1 made to differ from its third primitive on: a can 5 mm off.
    target = max(records, key=lambda r: r["index"])
    for fp in target["fingerprints"][3:]:
        first_object = sorted(fp["objects"])[0]
        fp["objects"][first_object][0] += 50
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    differ = subprocess.run([*MUBLE, "verify", str(run), "--workers", "1"], env=env, capture_output=True, text=True,
                            timeout=900)
    assert differ.returncode == 1, differ.stdout + differ.stderr[-2000:]
    assert f"mini {target['index']} " in differ.stdout
    assert f"after primitive 3 ({target['primitives'][2]})" in differ.stdout, differ.stdout
    assert "largest 50 units" in differ.stdout and "outcome success -> success" in differ.stdout
    bad = subprocess.run([*MUBLE, "verify", str(tmp_path / "nothing")], env=env, capture_output=True, text=True,
                         timeout=300)
    assert bad.returncode == 2 and "not a folder" in bad.stderr and "Traceback" not in bad.stderr
