"""`muble export`: generated sequences as a LeRobot-style dataset that reads back frame for frame."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow


def test_export_reads_back_one_row_per_keyframe(tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    root = tmp_path / "ds"
    subprocess.run([sys.executable, "-m", "muble.app.cli", "generate", "dataset.splits=[val]", "dataset.sizes=[1]",
                    "dataset.templates=[measure_weight_single]", "dataset.executor=serial", "renderer.width=106",
                    "renderer.height=60", f"dataset.root={root}", f"hydra.run.dir={tmp_path / 'run'}"],
                   check=True, capture_output=True, timeout=600)
    out = tmp_path / "lerobot"
    result = subprocess.run([sys.executable, "-m", "muble.app.cli", "export", str(root), "--split", "val",
                             "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    (sequence_path,) = (root / "val" / "sequences").glob("*.json")
    sequence = json.loads(sequence_path.read_text())
    rows = pq.read_table(out / "data" / "chunk-000" / "episode_000000.parquet").to_pylist()
    assert len(rows) == len(sequence["observations"])
    assert rows[0]["observation.state"][:3] == pytest.approx(sequence["observations"][0]["robot"]["pos"])
    assert [r["action.primitive"] for r in rows[:-1]] == [o["robot"]["action"][0] for o in sequence["observations"][1:]]
    assert all((out / r["observation.images.front"]).is_file() for r in rows)
    info = json.loads((out / "meta" / "info.json").read_text())
    assert info["total_frames"] == len(rows) and info["total_episodes"] == 1


def test_export_without_sequences_says_what_to_do(tmp_path):
    (tmp_path / "val").mkdir()
    result = subprocess.run([sys.executable, "-m", "muble.app.cli", "export", str(tmp_path), "--out",
                             str(tmp_path / "o")], capture_output=True, text=True, timeout=300)
    assert result.returncode == 2 and "dataset.sequences=true" in result.stderr
