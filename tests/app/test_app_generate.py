"""`muble generate`: deterministic, resumable after SIGKILL, identical on Ray and in one process."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from muble.io.atomic import TMP_PREFIX

pytestmark = pytest.mark.slow

SMALL = ["dataset.splits=[val]", "dataset.sizes=[3]", "dataset.sequences=false",
         "dataset.templates=[measure_weight_single,move_single,stack_simple]", "renderer.width=212",
         "renderer.height=120"]


def generate_cmd(root: Path, run_dir: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "muble.app.cli", "generate", *SMALL, f"dataset.root={root}",
            f"hydra.run.dir={run_dir}", *extra]


def tree(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    base = tmp_path_factory.mktemp("gen-ref")
    subprocess.run(generate_cmd(base / "ds", base / "run", "dataset.executor=serial"), check=True, timeout=600,
                   capture_output=True)
    return base / "ds"


def test_dataset_layout_and_manifest(reference):
    files = tree(reference)
    for i in range(3):
        assert f"val/scenes/SHOP_VRB2_val_{i:06d}.json" in files
        assert f"val/images/SHOP_VRB2_val_{i:06d}.png" in files
        assert f"val/instructions/SHOP_VRB2_val_{i:06d}.json" in files
    combined = json.loads(files["val/SHOP_VRB2_val_scenes.json"])
    assert len(combined["scenes"]) == 3 and combined["info"]["split"] == "val"
    instructions = json.loads(files["val/SHOP_VRB2_val_instructions.json"])["instructions"]
    assert all(ins["template_id"] in ("measure_weight_single", "move_single", "stack_simple") for ins in instructions)
    assert all(ins["ground_truth_actions"] for ins in instructions)
    manifest = json.loads(files["manifest.json"])
    assert set(manifest["files"]) == set(files) - {"manifest.json"}
    assert manifest["versions"]["mujoco"] and manifest["seeds"]["seed"] == 0


def test_sigkill_and_restart_gives_identical_dataset(reference, tmp_path):
    root = tmp_path / "ds"
    proc = subprocess.Popen(generate_cmd(root, tmp_path / "run1", "dataset.executor=serial"),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    marker_dir = root / "val" / "instructions"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and not (marker_dir.is_dir() and any(marker_dir.iterdir())):
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    partial = tree(root)
    assert len(partial) < len(tree(reference)), "the run finished before it could be killed"
    expected = tree(reference)
    for name, data in partial.items():  # every visible file is complete and already final
        if not Path(name).name.startswith(TMP_PREFIX) and not name.endswith(".lock"):  # the killed run's lock
            assert data == expected[name], name
    subprocess.run(generate_cmd(root, tmp_path / "run2", "dataset.executor=serial"), check=True, timeout=600,
                   capture_output=True)
    assert tree(root) == expected


def test_ray_two_workers_match_one_process(reference, tmp_path):
    pytest.importorskip("ray")
    root = tmp_path / "ds"
    result = subprocess.run(generate_cmd(root, tmp_path / "run", "dataset.executor=ray", "dataset.workers=2"),
                            timeout=900, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr[-3000:]
    assert tree(root) == tree(reference)


def test_bad_split_sizes_are_an_error(tmp_path):
    result = subprocess.run([sys.executable, "-m", "muble.app.cli", "generate", "dataset.splits=[val,test]",
                             "dataset.sizes=[3]", f"dataset.root={tmp_path / 'ds'}", f"hydra.run.dir={tmp_path}"],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 2 and "dataset.sizes" in result.stderr


def test_every_index_gets_the_template_asked_for(tmp_path):
    """The task mix draws further scene samples for an index until its template applies (stack_order needs three
    objects alike), so no index of the split is left without an instruction."""
    root = tmp_path / "ds"
    subprocess.run([sys.executable, "-m", "muble.app.cli", "generate", "dataset.splits=[val]", "dataset.sizes=[2]",
                    "dataset.templates=[stack_order]", "dataset.sequences=false", "dataset.executor=serial",
                    "generator.reach_check=false", "renderer.width=106", "renderer.height=60",
                    f"dataset.root={root}", f"hydra.run.dir={tmp_path}"],
                   check=True, capture_output=True, timeout=600)
    records = [json.loads(p.read_text()) for p in sorted((root / "val" / "instructions").glob("*.json"))]
    assert len(records) == 2 and all(r["instruction"] and r["template_id"] == "stack_order" for r in records)
    assert all((root / "val" / "scenes" / r["image_filename"].replace(".png", ".json")).is_file() for r in records)
    combined = json.loads((root / "val" / "SHOP_VRB2_val_instructions.json").read_text())["instructions"]
    assert len(combined) == len(records)
