"""`muble generate` into an existing root: a resume with other settings is refused before anything changes, a
second run of the same shard is refused while the first lives, a stale lock is taken over, and the manifest
never describes a dataset that is not on disk."""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from muble.core.errors import ConfigError
from muble.dataset.identity import IDENTITY_FILE, check_or_store_identity, dataset_identity
from muble.dataset.lock import RunLock
from tests.app.usage_probe import run_many

EMPTY = ["dataset.splits=[val]", "dataset.sizes=[0]", "dataset.executor=serial"]


def generate(root: Path, tmp_path: Path, *extra: str) -> list[str]:
    return ["generate", *EMPTY, f"dataset.root={root}", f"hydra.run.dir={tmp_path / 'run'}", *extra]


def test_resume_with_another_seed_is_refused_and_nothing_changes(tmp_path):
    root = tmp_path / "ds"
    first, second, again = run_many([generate(root, tmp_path), generate(root, tmp_path, "seed=1"),
                                     generate(root, tmp_path, "dataset.sizes=[0]", "dataset.start=5")], tmp_path)
    assert first["code"] == 0, first
    manifest = (root / "manifest.json").read_bytes()
    assert second["code"] == 2 and "seed: stored 0, requested 1" in second["stderr"], second
    assert "another dataset.root" in second["stderr"] and "Traceback" not in second["stderr"]
    assert (root / "manifest.json").read_bytes() == manifest  # the refused run changed nothing
    assert again["code"] == 0, again  # other indices of the same dataset: an extension, allowed


def test_identity_names_every_difference_and_ignores_how_and_which():
    base = {"seed": 0, "robot": {"name": "Panda"}, "output": {"dir": "a"},
            "dataset": {"root": "/a", "workers": 2, "sizes": [3], "templates": ["x"]}}
    other = json.loads(json.dumps(base))
    other["dataset"].update(root="/b", workers=8, sizes=[30])  # where, how and how many: same dataset
    other["output"]["dir"] = "b"
    assert dataset_identity(base) == dataset_identity(other)
    other["robot"]["name"], other["dataset"]["templates"] = "UR5e", ["y"]
    assert dataset_identity(base) != dataset_identity(other)


def test_identity_check_lists_the_differences(tmp_path):
    check_or_store_identity(tmp_path, {"seed": 0, "robot": {"name": "Panda"}, "dataset": {}})
    assert (tmp_path / IDENTITY_FILE).is_file()
    with pytest.raises(ConfigError) as info:
        check_or_store_identity(tmp_path, {"seed": 2, "robot": {"name": "UR5e"}, "dataset": {}})
    assert "robot.name: stored \"Panda\", requested \"UR5e\"" in str(info.value) and "seed" in str(info.value)


def test_a_dataset_made_under_the_controller_s_old_name_resumes_under_the_new_one(tmp_path):
    check_or_store_identity(tmp_path, {"seed": 0, "robot": {"name": "Panda", "controller": "OSC_POSE"}, "dataset": {}})
    check_or_store_identity(tmp_path, {"seed": 0, "robot": {"name": "Panda", "controller": "IK_JOINT_SERVO"},
                                       "dataset": {}})  # the same controller: no difference
    with pytest.raises(ConfigError, match="robot.controller"):
        check_or_store_identity(tmp_path, {"seed": 0, "robot": {"name": "Panda", "controller": "OTHER"}, "dataset": {}})


def test_a_dataset_made_before_stages_resumes_on_the_stage_it_stands_on(tmp_path):
    made_before = {"seed": 0, "robot": {"name": "Panda"}, "generator": {"min_objects": 4}, "dataset": {}}
    check_or_store_identity(tmp_path, made_before)
    now = {"seed": 0, "robot": {"name": "Panda", "stage": None}, "generator": {"min_objects": 4, "stage": None},
           "dataset": {}}
    check_or_store_identity(tmp_path, now)  # null: each scene's own stage, as before stages could be chosen
    with pytest.raises(ConfigError, match='robot.stage: not stored, requested "original"'):
        check_or_store_identity(tmp_path, {**now, "robot": {"name": "Panda", "stage": "original"}})
    # Its scenes stand on robosuite's stage, which generator.stage=robosuite names now (the protocol's setting);
    # the generator's default, the original's, would mix another stage into it.
    check_or_store_identity(tmp_path, {**now, "generator": {"min_objects": 4, "stage": "robosuite"}})
    with pytest.raises(ConfigError, match='generator.stage: not stored, requested "original"'):
        check_or_store_identity(tmp_path, {**now, "generator": {"min_objects": 4, "stage": "original"}})
    stored_null = tmp_path / "stored_null"
    stored_null.mkdir()
    check_or_store_identity(stored_null, now)
    check_or_store_identity(stored_null, {**now, "generator": {"min_objects": 4, "stage": "robosuite"}})
    with pytest.raises(ConfigError, match='generator.stage: stored null, requested "original"'):
        check_or_store_identity(stored_null, {**now, "generator": {"min_objects": 4, "stage": "original"}})


def test_a_dataset_made_before_hidden_physical_properties_resumes_without_them(tmp_path):
    made_before = {"seed": 0, "generator": {"min_objects": 4}, "dataset": {}}
    check_or_store_identity(tmp_path, made_before)
    check_or_store_identity(tmp_path, {**made_before, "generator": {"min_objects": 4, "physical_properties": []}})
    with pytest.raises(ConfigError, match=r'generator.physical_properties: not stored, requested \["friction"\]'):
        check_or_store_identity(tmp_path, {**made_before, "generator": {"min_objects": 4,
                                                                        "physical_properties": ["friction"]}})


def test_a_dataset_storing_the_generators_own_image_size_and_step_resumes_on_the_settings_that_own_them(tmp_path):
    stored = {"seed": 0, "robot": {"name": "Panda", "timestep": 0.002}, "renderer": {"width": 848, "height": 480},
              "generator": {"min_objects": 4, "image_width": 848, "image_height": 480, "timestep": 0.002},
              "dataset": {}}
    (tmp_path / IDENTITY_FILE).write_text(json.dumps(dataset_identity(stored)))
    now = {**stored, "generator": {"min_objects": 4}}
    check_or_store_identity(tmp_path, now)  # the same image size and physics step, named once now
    with pytest.raises(ConfigError, match='generator.image_width: stored 848, not requested'):
        check_or_store_identity(tmp_path, {**now, "renderer": {"width": 424, "height": 480}})
    with pytest.raises(ConfigError, match='generator.timestep: stored 0.002, not requested'):
        check_or_store_identity(tmp_path, {**now, "robot": {"name": "Panda", "timestep": 0.001}})


def test_a_live_owner_is_refused_and_a_stale_lock_taken_over(tmp_path):
    root = tmp_path / "ds"
    root.mkdir()
    lock = root / ".muble-generate-shard0of1.lock"
    owner = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])  # a live owner
    try:
        lock.write_text(json.dumps({"pid": owner.pid, "host": socket.gethostname(), "started": "earlier"}))
        (refused,) = run_many([generate(root, tmp_path)], tmp_path)
        assert refused["code"] == 2 and f"process {owner.pid}" in refused["stderr"], refused
        assert lock.exists() and not (root / "manifest.json").exists()
    finally:
        owner.kill()
        owner.wait()
    # The same lock, its owner gone: stale, taken over, and released at the end.
    (taken,) = run_many([generate(root, tmp_path)], tmp_path)
    assert taken["code"] == 0, taken
    assert not lock.exists() and (root / "manifest.json").is_file()


def test_a_reused_pid_does_not_hold_the_lock(tmp_path):
    path = tmp_path / "x.lock"  # this process's pid, but a start time that is not this process's
    path.write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "start_ticks": 1}))
    with RunLock(path, "the folder"):
        assert json.loads(path.read_text())["start_ticks"] != 1


def test_run_lock_is_exclusive(tmp_path):
    path = tmp_path / "x.lock"
    with RunLock(path, "the folder"):
        assert json.loads(path.read_text())["pid"] == os.getpid()
        with pytest.raises(ConfigError, match="in use by process"):
            RunLock(path, "the folder").acquire()
    assert not path.exists()


def test_a_dataset_made_by_another_generator_version_is_not_resumed(tmp_path):
    """The same settings make other files under another generator version (muble.generation.generator
    GENERATOR_VERSION): a folder made by an older one is refused rather than extended into a mix."""
    config = {"seed": 0, "robot": {"name": "Panda"}, "dataset": {}}
    older = {k: v for k, v in dataset_identity(config).items() if k != "generator_version"}
    (tmp_path / IDENTITY_FILE).write_text(json.dumps(older))
    with pytest.raises(ConfigError, match="generator_version: not stored, requested"):
        check_or_store_identity(tmp_path, config)
