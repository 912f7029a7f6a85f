"""Local workers die with their parent: a `kill -9` of the process that owns a pool leaves no worker behind."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

POOL_OWNER = """
import os, sys, time
from muble.dataset.executors import run_all

def work(i):
    with open(os.path.join(sys.argv[1], f"worker-{os.getpid()}"), "w"):
        pass
    time.sleep(120)
    return i

if __name__ == "__main__":
    for _ in run_all("processes", work, range(2), workers=2):
        pass
"""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    status = Path(f"/proc/{pid}/status")
    return not (status.exists() and "State:\tZ" in status.read_text())  # a zombie is dead


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process checks read /proc")
def test_pool_workers_die_within_seconds_of_a_killed_parent(tmp_path):
    script = tmp_path / "owner.py"
    script.write_text(POOL_OWNER)
    owner = subprocess.Popen([sys.executable, str(script), str(tmp_path)], cwd=tmp_path)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and len(list(tmp_path.glob("worker-*"))) < 2:
            time.sleep(0.1)
        pids = [int(p.name.split("-")[1]) for p in tmp_path.glob("worker-*")]
        assert len(pids) == 2 and all(_alive(pid) for pid in pids)
        owner.send_signal(signal.SIGKILL)
        owner.wait()
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and any(_alive(pid) for pid in pids):
            time.sleep(0.1)
        assert not any(_alive(pid) for pid in pids), "pool workers outlived their killed parent"
    finally:
        owner.kill()
        for p in tmp_path.glob("worker-*"):
            try:
                os.kill(int(p.name.split("-")[1]), signal.SIGKILL)
            except ProcessLookupError:
                pass


POOL_REPLACING_WORKERS = """
import os, time
from muble.dataset.executors import run_all

def work(i):
    time.sleep(0.02)
    return i, os.getpid()

if __name__ == "__main__":
    results = list(run_all("processes", work, range(130), workers=2))
    print(len(results), len({i for i, _ in results}), len({pid for _, pid in results}))
"""


def test_a_pool_whose_workers_were_replaced_finishes_and_returns(tmp_path):
    """130 items on 2 workers renewed every 100 items (2 x ``TASKS_PER_WORKER``): every result arrives, from
    workers of both batches, and the owner returns (a pool that replaced its workers itself could hang as it
    ended)."""
    script = tmp_path / "owner.py"
    script.write_text(POOL_REPLACING_WORKERS)
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stderr[-2000:]
    results, distinct, workers = (int(v) for v in done.stdout.split()[-3:])
    assert results == distinct == 130
    assert workers >= 3  # workers were renewed
