"""Every usage or environment error of the command line exits 2 with one paragraph, no traceback, and leaves
nothing behind; Ctrl-C exits 130 with one line saying how to carry on; a resume never loses data quietly."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

LONG = 10_000


def muble(*args: str, env: dict | None = None, cwd: Path | None = None) -> subprocess.CompletedProcess:
    full_env = {**os.environ, "MUJOCO_GL": "egl", **(env or {})}
    return subprocess.run([sys.executable, "-m", "muble.app.cli", *args], capture_output=True, text=True,
                          env=full_env, cwd=cwd, timeout=300)


def assert_usage_error(done: subprocess.CompletedProcess, *words: str) -> None:
    assert done.returncode == 2, (done.returncode, done.stderr[-2000:])
    assert "Traceback" not in done.stderr and "Traceback" not in done.stdout, done.stderr[-2000:]
    errors = [line for line in done.stderr.splitlines() if "error:" in line]
    assert len(errors) == 1, done.stderr[-2000:]
    for word in words:
        assert word in errors[0], errors[0][:500]


CASES = {
    "long seed": (["dry_run=true", "seed=" + "9" * LONG], "command line"),
    "long output dir": (["dry_run=true", "output.dir=/tmp/" + "d" * LONG], "too long"),
    "long task": (["dry_run=true", "task=" + "t" * LONG], "too long"),
    "long key": (["dry_run=true", "k" * LONG + "=1"], ""),
    "output dir is a file": (["dry_run=true", "output.dir=/etc/hostname"], "folder"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_usage_errors_exit_2_in_one_paragraph(case, tmp_path):
    args, word = CASES[case]
    done = muble(*args, f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert_usage_error(done, word)
    assert not (tmp_path / "run").exists() or not any((tmp_path / "run").rglob("*.json"))
    # A message that names a 10,000-character path shortens it.
    assert len(done.stderr) < 2000


def test_an_unknown_gl_backend_is_an_environment_error(tmp_path):
    assert_usage_error(muble("dry_run=true", env={"MUJOCO_GL": "garbage"}, cwd=tmp_path), "MUJOCO_GL", "egl")


GENERATE = ["generate", "dataset.splits=[v]", "dataset.sequences=false", "dataset.workers=1",
            "renderer.width=106", "renderer.height=60"]


def test_a_failed_generate_leaves_no_folder_it_made(tmp_path):
    root = tmp_path / "ds"
    done = muble(*GENERATE, "dataset.sizes=[1]", "dataset.executor=nope", f"dataset.root={root}",
                 f"hydra.run.dir={tmp_path / 'run'}")
    assert_usage_error(done, "executor")
    assert not root.exists()


@pytest.mark.slow
def test_resumes_that_would_lose_data_are_refused_and_truncated_settings_named(tmp_path):
    root = tmp_path / "ds"
    done = muble(*GENERATE, "dataset.sizes=[2]", f"dataset.root={root}", f"hydra.run.dir={tmp_path / 'r1'}")
    assert done.returncode == 0, done.stderr[-2000:]
    combined = root / "v" / "SHOP_VRB2_v_instructions.json"
    before = json.loads(combined.read_text())
    # A smaller split would drop index 1 from the combined file; other sharding would mix two layouts.
    assert_usage_error(muble(*GENERATE, "dataset.sizes=[1]", f"dataset.root={root}",
                             f"hydra.run.dir={tmp_path / 'r2'}"), "stored size 2")
    assert_usage_error(muble(*GENERATE, "dataset.sizes=[2]", "dataset.num_shards=2", f"dataset.root={root}",
                             f"hydra.run.dir={tmp_path / 'r3'}"), "num_shards")
    assert json.loads(combined.read_text()) == before and (root / "manifest.json").is_file()
    # A truncated settings file is named, not a traceback.
    settings = root / "dataset_config.json"
    settings.write_text(settings.read_text()[:40])
    assert_usage_error(muble(*GENERATE, "dataset.sizes=[2]", f"dataset.root={root}",
                             f"hydra.run.dir={tmp_path / 'r4'}"), "dataset_config.json", "truncated")


@pytest.mark.slow
def test_ctrl_c_exits_130_with_one_line(tmp_path):
    root = tmp_path / "ds"
    cmd = [sys.executable, "-m", "muble.app.cli", *GENERATE, "dataset.sizes=[20]", "dataset.workers=2",
           f"dataset.root={root}", f"hydra.run.dir={tmp_path / 'run'}"]
    # A terminal's program takes Ctrl-C; a shell's background job (`pytest … &`, `nohup`) ignores SIGINT, and a
    # process started from it would inherit that and finish the run. With a handler installed here, the child
    # starts with SIGINT's default whatever this process inherited.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                env={**os.environ, "MUJOCO_GL": "egl"}, start_new_session=True)
    finally:
        signal.signal(signal.SIGINT, previous)
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not any((root / "v" / "instructions").glob("*.json")):
        time.sleep(0.1)
    os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole process group
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, (proc.returncode, err[-2000:])
    assert "Traceback" not in err, err[-3000:]
    assert "run the same command again" in err
