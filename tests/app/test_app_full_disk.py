"""`muble generate` on a full disk: exit 2 with one line naming the disk and what to do, nothing half-written left
(no temporaries, every JSON and PNG whole, the previous manifest in place), and the same command carries on once
there is space.

The disk is real where this machine allows mounting a small tmpfs (root, as CI runs); the simulated variant, which
always runs, fails the process's file writes with ENOSPC once a byte budget is spent, as a full disk fails write(2):
part of the data written, then the error, naming no file."""
from __future__ import annotations

import errno
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from PIL import Image

from muble.app.usage import environment_error
from muble.io.atomic import TMP_PREFIX, write_bytes_atomic
from muble.io.manifest import sha256_file

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="mounts a tmpfs")

REPO = Path(__file__).resolve().parents[2]
GENERATE = ["generate", "dataset.splits=[v]", "dataset.sequences=false", "dataset.workers=1",
            "dataset.executor=serial", "renderer.width=106", "renderer.height=60"]
DISK_BYTES = 1 << 20  # the small disk: 1 MiB
FREE_BYTES = 3 * 4096  # left free on it: the settings fit, index 1's image (about 7 kB) does not

# Runs `muble` with every binary file written through os.fdopen (the atomic writer's way) failing with ENOSPC once
# BUDGET bytes are written: the bytes that fit are written, then write(2)'s error, which names no file.
FULL_DISK_MUBLE = """
import errno, io, os, sys

budget = [int(sys.argv[1])]
real_fdopen = os.fdopen


class FullDisk(io.FileIO):
    def write(self, data):
        data = bytes(data)
        if len(data) > budget[0]:
            fits, budget[0] = data[:budget[0]], 0
            if fits:
                super().write(fits)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        budget[0] -= len(data)
        return super().write(data)


def fdopen(fd, mode="r", *args, **kwargs):
    if "b" in mode and ("w" in mode or "a" in mode):
        return FullDisk(fd, mode.replace("b", "") + "b")
    return real_fdopen(fd, mode, *args, **kwargs)


os.fdopen = fdopen
from muble.app.cli import main

sys.exit(main(sys.argv[2:]))
"""


def muble(*args: str, prefix: list[str] | None = None) -> subprocess.CompletedProcess:
    command = prefix or [sys.executable, "-m", "muble.app.cli"]
    return subprocess.run([*command, *args], capture_output=True, text=True, cwd=REPO, timeout=600,
                          env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")})


@pytest.fixture(scope="module")
def one_scene(tmp_path_factory) -> Path:
    """A finished dataset of one scene, to be extended to two on a full disk."""
    where = tmp_path_factory.mktemp("one_scene")
    done = muble(*GENERATE, "dataset.sizes=[1]", f"dataset.root={where / 'ds'}", f"hydra.run.dir={where / 'run'}")
    assert done.returncode == 0, done.stderr[-3000:]
    return where / "ds"


@pytest.fixture
def small_disk(tmp_path) -> Path:
    """A 1 MiB tmpfs, unmounted after the test; skips where this process may not mount one."""
    disk = tmp_path / "disk"
    disk.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={DISK_BYTES}", "muble-full-disk", str(disk)],
                             capture_output=True, text=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here (needs root or CAP_SYS_ADMIN): {mounted.stderr.strip()}; "
                    "test_generate_on_a_simulated_full_disk covers the same path")
    try:
        yield disk
    finally:
        if subprocess.run(["umount", str(disk)], capture_output=True).returncode != 0:
            subprocess.run(["umount", "-l", str(disk)], capture_output=True)


def fill(disk: Path, leave: int) -> Path:
    """Fill ``disk`` up, then give back ``leave`` bytes."""
    filler = disk / "filler"
    chunk = b"\0" * (1 << 16)
    with open(filler, "wb") as f:
        try:
            while True:
                f.write(chunk)
                f.flush()
        except OSError as e:
            assert e.errno == errno.ENOSPC, e
    os.truncate(filler, max(0, filler.stat().st_size - leave))
    return filler


def assert_full_disk_error(done: subprocess.CompletedProcess, *words: str) -> str:
    assert done.returncode == 2, (done.returncode, done.stderr[-3000:])
    assert "Traceback" not in done.stderr + done.stdout, done.stderr[-3000:]
    errors = [line for line in done.stderr.splitlines() if "error:" in line]
    assert len(errors) == 1, done.stderr[-3000:]
    for word in ("No space left on device", "is full", "free space", "run the same command again", *words):
        assert word in errors[0], errors[0]
    return errors[0]


def assert_nothing_half_written(root: Path, manifest_before: bytes) -> None:
    assert not [p for p in root.rglob("*") if p.name.startswith(TMP_PREFIX)], "a temporary file was left"
    for path in root.rglob("*.json"):
        json.loads(path.read_text())  # whole, or not there at all
    for path in root.rglob("*.png"):
        with Image.open(path) as image:
            image.load()
    # The previous run's manifest stays until a run finishes and writes its own.
    assert (root / "manifest.json").read_bytes() == manifest_before


def assert_complete(root: Path, indices: list[int]) -> None:
    files = json.loads((root / "manifest.json").read_text())["files"]
    for i in indices:
        for kind, ext in (("scenes", "json"), ("images", "png"), ("instructions", "json")):
            assert f"v/{kind}/SHOP_VRB2_v_{i:06d}.{ext}" in files, sorted(files)
    for rel, digest in files.items():
        assert sha256_file(root / rel) == digest, rel


def test_a_write_that_fails_names_its_file_and_keeps_the_old_one(tmp_path, monkeypatch):
    path = tmp_path / "out" / "scene.json"
    write_bytes_atomic(path, b"old")

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # as fsync(2) reports it: no file named

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OSError) as info:
        write_bytes_atomic(path, b"new")
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(path)
    assert path.read_bytes() == b"old" and [p.name for p in path.parent.iterdir()] == ["scene.json"]


def test_the_full_disk_message_names_the_folder_its_disk_and_what_to_do(tmp_path):
    message = environment_error(OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "new" / "a.png")))
    assert f"cannot use {tmp_path / 'new' / 'a.png'}" in message
    assert f"the disk holding {tmp_path} (mounted at /" in message and " free of " in message
    assert "free space on it" in message and "run the same command again" in message


@pytest.mark.slow
def test_generate_on_a_full_disk(one_scene, small_disk, tmp_path):
    root = small_disk / "ds"
    shutil.copytree(one_scene, root)
    manifest_before = (root / "manifest.json").read_bytes()
    filler = fill(small_disk, FREE_BYTES)

    done = muble(*GENERATE, "dataset.sizes=[2]", f"dataset.root={root}", f"hydra.run.dir={tmp_path / 'run1'}")
    line = assert_full_disk_error(done, f"mounted at {small_disk}", str(root))
    assert "kB free of 1.0 MB" in line, line
    assert_nothing_half_written(root, manifest_before)

    filler.unlink()
    done = muble(*GENERATE, "dataset.sizes=[2]", f"dataset.root={root}", f"hydra.run.dir={tmp_path / 'run2'}")
    assert done.returncode == 0, done.stderr[-3000:]
    assert_complete(root, [0, 1])


@pytest.mark.slow
def test_generate_on_a_simulated_full_disk(one_scene, tmp_path):
    root = tmp_path / "ds"
    shutil.copytree(one_scene, root)
    manifest_before = (root / "manifest.json").read_bytes()
    script = tmp_path / "full_disk_muble.py"
    script.write_text(FULL_DISK_MUBLE)

    done = muble(*GENERATE, "dataset.sizes=[2]", f"dataset.root={root}", f"hydra.run.dir={tmp_path / 'run'}",
                 prefix=[sys.executable, str(script), str(FREE_BYTES)])
    # write(2) named no file: the writer names the one it was writing, and the message its folder and disk.
    line = assert_full_disk_error(done, f"cannot use {root / 'v'}", f"the disk holding {root / 'v'}")
    assert "SHOP_VRB2_v_000001" in line, line
    assert_nothing_half_written(root, manifest_before)
