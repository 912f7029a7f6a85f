"""The frozen protocols end to end: the shipped splits are the recorded ones, `muble generate protocol=shopvrb2_v2`
reproduces them file by file under every BLAS kernel and numpy SIMD level this CPU can run, `muble eval` runs the
shipped files with no generation and labels results with the protocol only on its data, and `muble data` writes
them to a folder.

Each index is generated on its own from (seed, split, index), so the first indices of a split are checked file by
file against the manifest recorded in the package.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from muble.dataset.protocol import (data_manifest, load_protocol, manifest_hash, recorded_manifest, shipped_archive,
                                    shipped_files)
from tests.support.cpu import cpu_settings

MUBLE = [sys.executable, "-m", "muble.app.cli"]
V2 = "shopvrb2_v2"
SHIPPED = {"shopvrb2_v1": ["mini"],
           V2: ["mini", "test", "unseen_objects", "unseen_properties", "perturbed_views", "long_horizon", "physical",
                "closed_loop", "noisy_sensing"]}


def muble(*args: str, cwd: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), **(env or {})}
    return subprocess.run([*MUBLE, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=900)


# --- the shipped files -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name, split", [(n, s) for n, splits in SHIPPED.items() for s in splits])
def test_every_shipped_split_is_the_recorded_one(name, split):
    protocol = load_protocol(name)
    spec = protocol["splits"][split]
    recorded = recorded_manifest(protocol, split)
    assert spec["sha256"] == manifest_hash(recorded)
    files = shipped_files(protocol, split)  # checks every file against the manifest
    assert len(files) == 2 * spec["size"] == len(recorded)
    scene = json.loads(next(v for k, v in files.items() if "/scenes/" in k))
    assert (scene.get("stage") == "original") == (name == V2)  # v2 stands on the original desk, v1 on robosuite's


def test_train_is_generated_not_shipped_and_the_wheel_data_stays_small():
    protocol = load_protocol(V2)
    assert shipped_archive(protocol, "train") is None
    total = sum(shipped_archive(load_protocol(n), s).stat().st_size for n, splits in SHIPPED.items() for s in splits)
    assert total < 10 * 2**20, total


def test_v1_is_not_regenerated_and_v2_names_what_regeneration_can_change(tmp_path):
    done = muble("generate", "protocol=shopvrb2_v1", f"dataset.root={tmp_path / 'v1'}", cwd=tmp_path)
    assert done.returncode == 2 and "not regenerated" in done.stderr and "muble data" in done.stderr, done.stderr
    assert not (tmp_path / "v1").exists()


# --- muble data ----------------------------------------------------------------------------------------------------
def test_muble_data_writes_the_recorded_files_and_refuses_bad_input(tmp_path):
    out = tmp_path / "data"
    done = muble("data", f"protocol={V2}", "benchmark.split=unseen_objects", f"--out={out}", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    protocol = load_protocol(V2)
    assert data_manifest(out, "unseen_objects") == recorded_manifest(protocol, "unseen_objects")
    again = muble("data", f"protocol={V2}", "benchmark.split=unseen_objects", f"--out={out}", cwd=tmp_path)
    assert again.returncode == 2 and "exists" in again.stderr
    for args, words in ((["benchmark.split=nope"], "unknown split 'nope' of protocol"),
                        (["benchmark.split=train"], "does not ship"), ([], "--out")):
        bad = tmp_path / "bad"
        done = muble("data", f"protocol={V2}", *args, *([f"--out={bad}"] if args else []), cwd=tmp_path)
        assert done.returncode == 2 and words in done.stderr and "Traceback" not in done.stderr, done.stderr
        assert not bad.exists()
    done = muble("data", "protocol=shopvrb2_v9", f"--out={tmp_path / 'x'}", cwd=tmp_path)
    assert done.returncode == 2 and "shopvrb2_v2" in done.stderr


# --- muble eval on the shipped files -------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("name", [V2, "shopvrb2_v1"])
def test_eval_runs_the_shipped_split_with_no_generation(tmp_path, name):
    out = tmp_path / "eval"
    env = {"MUBLE_DATA_CACHE": str(tmp_path / "cache")}
    done = muble("eval", f"protocol={name}", "agent=random", "evaluation.limit=2", "dataset.workers=1",
                 f"hydra.run.dir={out}", cwd=tmp_path, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads((out / "report.json").read_text())
    protocol = load_protocol(name)
    assert report["protocol"] == name and report["protocol_data"]["matches"] is True
    assert report["protocol_data"]["data_sha256"] == protocol["splits"]["mini"]["sha256"]
    results = json.loads((out / "results.json").read_text())
    assert results["protocol"] == name and len(results["splits"]["mini"]["episodes"]) == 2


@pytest.mark.slow
def test_eval_labels_only_the_protocols_data(tmp_path):
    root = tmp_path / "data"
    assert muble("data", f"protocol={V2}", f"--out={root}", cwd=tmp_path).returncode == 0
    scene = sorted((root / "mini" / "scenes").glob("*.json"))[0]
    scene.write_text(scene.read_text().replace('"split"', '"split" ', 1))
    bad = tmp_path / "eval_changed"
    done = muble("eval", f"protocol={V2}", "agent=random", f"dataset.root={root}", "dataset.workers=1",
                 f"hydra.run.dir={bad}", cwd=tmp_path)
    assert done.returncode == 2 and "1 of its files differ" in done.stderr and scene.name in done.stderr, \
        done.stderr[-2000:]
    assert "Traceback" not in done.stderr and not (bad / "report.json").exists()


# --- regeneration on every CPU setting ---------------------------------------------------------------------------
# (split, first index, count): in-distribution scenes, a held-out split's, and a jittered camera's and lamps'.
SAMPLE = [("mini", 0, 3), ("perturbed_views", 0, 1), ("unseen_objects", 7, 1), ("physical", 0, 2),
          ("closed_loop", 0, 2), ("noisy_sensing", 0, 2)]


def _regenerate(tmp_path: Path, label: str, env: dict[str, str], workers: int = 1) -> dict[str, str]:
    files = {}
    for split, start, count in SAMPLE:
        root = tmp_path / f"{label}_{split}"
        done = muble("generate", f"protocol={V2}", f"benchmark.split={split}", f"dataset.start={start}",
                     f"protocol.splits.{split}.size={count}", f"protocol.splits.{split}.sha256=null",
                     f"dataset.root={root}", f"dataset.workers={workers}", f"hydra.run.dir={root}.run",
                     cwd=tmp_path, env=env)
        assert done.returncode == 0, (label, done.stderr[-3000:])
        files.update(data_manifest(root, split))
    return files


@pytest.mark.slow
def test_generation_gives_the_shipped_files_under_every_cpu_setting(tmp_path):
    protocol = load_protocol(V2)
    recorded = {k: v for split, _, _ in SAMPLE for k, v in recorded_manifest(protocol, split).items()}
    settings = cpu_settings()
    assert len(settings) >= 3, settings  # the default and at least two other kernels
    for label, env in settings.items():
        found = _regenerate(tmp_path, label, env, workers=2 if label == "default" else 1)
        assert len(found) == 2 * sum(n for _, _, n in SAMPLE)
        differ = sorted(k for k, v in found.items() if recorded.get(k) != v)
        assert not differ, (label, env, differ)
