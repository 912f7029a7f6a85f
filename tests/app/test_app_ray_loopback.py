"""`dataset.executor=ray` without `dataset.ray_address` starts a cluster only this machine can reach: every listening
TCP socket of the run is on the loopback interface, its token and session files lie in a folder only this user
can enter, and that folder is gone when the run ends."""
from __future__ import annotations

import errno
import ipaddress
import os
import shutil
import stat
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

pytest.importorskip("ray")
pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads sockets and processes in /proc")

RAY_OWNER = """
import os, sys, time
from pathlib import Path
from muble.dataset.executors import run_all

def work(job):
    i, marks = job[0], Path(job[1])
    (marks / f"task-{i}").write_text(str(os.getpid()))
    while not (marks / "release").exists():  # held until the test has read the sockets
        time.sleep(0.1)
    return i

if __name__ == "__main__":
    print(sorted(run_all("ray", work, [(i, sys.argv[1]) for i in range(2)], workers=2)), flush=True)
"""

TCP_LISTEN = "0A"  # the state column of /proc/net/tcp{,6}


def descendants(pid: int) -> list[int]:
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            ppid = int(Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        children.setdefault(ppid, []).append(int(entry))
    found, todo = [], [pid]
    while todo:
        current = todo.pop()
        found.append(current)
        todo.extend(children.get(current, []))
    return found


def socket_inodes(pid: int) -> set[str]:
    inodes = set()
    try:
        fds = os.listdir(f"/proc/{pid}/fd")
    except OSError:
        return inodes
    for fd in fds:
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[len("socket:["):-1])
    return inodes


def _address(hex_address: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    raw = bytes.fromhex(hex_address)
    # The kernel prints each 32-bit word in host (little-endian) order.
    return ipaddress.ip_address(b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4)))


def listening_sockets() -> dict[str, tuple[ipaddress.IPv4Address | ipaddress.IPv6Address, int]]:
    """Every listening TCP socket of this network namespace: inode -> (address, port)."""
    found = {}
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        if not os.path.exists(table):
            continue
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == TCP_LISTEN:
                hex_address, hex_port = fields[1].split(":")
                found[fields[9]] = (_address(hex_address), int(hex_port, 16))
    return found


def is_loopback(address: ipaddress.IPv4Address | ipaddress.IPv6Address) -> bool:
    mapped = getattr(address, "ipv4_mapped", None)  # ::ffff:127.0.0.1, a dual-stack socket's IPv4 loopback
    return address.is_loopback or (mapped is not None and mapped.is_loopback)


def test_address_decoding():
    assert _address("0100007F") == ipaddress.ip_address("127.0.0.1")
    assert _address("0000000000000000FFFF00000100007F") == ipaddress.ip_address("::ffff:127.0.0.1")
    assert _address("00000000000000000000000001000000") == ipaddress.ip_address("::1")
    assert is_loopback(_address("0000000000000000FFFF00000100007F"))
    assert not is_loopback(_address("00000000000000000000000000000000"))  # ::, every interface
    assert not is_loopback(_address("020200C0"))  # 192.0.2.2


def private_ray_env(home: Path) -> tuple[Path, dict[str, str]]:
    """A short temporary folder (Ray's Unix sockets live under it and their paths must stay under 107 characters)
    and an environment that starts a private cluster there, with ``home`` as HOME and no cluster to join."""
    tmp = Path(tempfile.mkdtemp(prefix="mt-", dir="/tmp"))
    env = {**os.environ, "TMPDIR": str(tmp), "HOME": str(home)}
    for key in ("RAY_ADDRESS", "RAY_AUTH_MODE", "RAY_AUTH_TOKEN", "RAY_AUTH_TOKEN_PATH"):
        env.pop(key, None)
    return tmp, env


def _alive(pid: int) -> bool:
    status = Path(f"/proc/{pid}/status")
    try:
        return "State:\tZ" not in status.read_text()
    except OSError:
        return False


def test_a_private_ray_cluster_listens_only_on_loopback_and_keeps_its_files_private(tmp_path):
    marks, home = tmp_path / "marks", tmp_path / "home"
    marks.mkdir()
    home.mkdir()
    script = tmp_path / "owner.py"
    script.write_text(RAY_OWNER)
    tmp, env = private_ray_env(home)
    owner = subprocess.Popen([sys.executable, str(script), str(marks)], cwd=Path(__file__).parents[2], env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    pids: list[int] = []
    try:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and len(list(marks.glob("task-*"))) < 2 and owner.poll() is None:
            time.sleep(0.2)
        assert len(list(marks.glob("task-*"))) == 2, owner.communicate(timeout=60)[1][-3000:]

        pids = descendants(owner.pid)
        listening = listening_sockets()
        seen = []
        for pid in pids:
            try:
                command = Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " ")
            except OSError:
                continue
            for inode in socket_inodes(pid):
                if inode in listening:
                    seen.append((command, *listening[inode]))
        # Whole command lines: a deep checkout pushes the program's name past any fixed cut.
        commands = " ".join(c for c, _, _ in seen)
        # The GCS, the raylet and the workers were all found: the check below is not vacuous.
        programs = [(c.split(" ")[0][-40:], a, p) for c, a, p in seen]
        assert "gcs_server" in commands and "raylet" in commands and len(seen) >= 4, programs
        exposed = [s for s in seen if not is_loopback(s[1])]
        assert not exposed, f"listening beyond the loopback interface: {exposed}"

        folders = list(tmp.glob("muble-ray-*"))
        assert len(folders) == 1, list(tmp.iterdir())
        mode = stat.S_IMODE(folders[0].stat().st_mode)
        assert mode & 0o077 == 0, oct(mode)  # Ray's own session folders inside are 0777: this one guards them
        token = folders[0] / "auth_token"
        assert stat.S_IMODE(token.stat().st_mode) == 0o600 and len(token.read_text()) == 64
        assert not (home / ".ray").exists(), "Ray wrote a token into HOME"

        (marks / "release").touch()
        out, err = owner.communicate(timeout=120)
        assert owner.returncode == 0, err[-3000:]
        assert out.strip().splitlines()[-1] == "[0, 1]"
        assert not folders[0].exists(), "the private Ray folder outlived the run"
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and any(_alive(pid) for pid in pids[1:]):
            time.sleep(0.2)
        assert not any(_alive(pid) for pid in pids[1:]), "Ray processes outlived the run"
    finally:
        (marks / "release").touch()
        if owner.poll() is None:
            owner.kill()
            owner.communicate()
        for pid in pids[1:]:
            if _alive(pid):
                try:
                    os.kill(pid, 9)
                except ProcessLookupError:
                    pass
        shutil.rmtree(tmp, ignore_errors=True)


RAY_FULL_DISK = """
import errno, os, sys
from muble.dataset.executors import run_all

def work(path):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), path)

if __name__ == "__main__":
    try:
        list(run_all("ray", work, [sys.argv[1]], workers=1))
    except OSError as e:
        print(type(e).__name__, e.errno, e.filename, flush=True)
"""


def test_a_full_disk_in_a_ray_worker_reaches_the_caller_as_the_workers_own_error(tmp_path):
    script = tmp_path / "full.py"
    script.write_text(RAY_FULL_DISK)
    tmp, env = private_ray_env(tmp_path)
    try:
        done = subprocess.run([sys.executable, str(script), str(tmp_path / "scene.json")], env=env, text=True,
                              capture_output=True, timeout=300, cwd=Path(__file__).parents[2])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    # The OSError itself (not Ray's RayTaskError wrapping it), with its errno and file, as the process pool gives.
    assert done.stdout.split() == ["OSError", str(errno.ENOSPC), str(tmp_path / "scene.json")], done.stderr[-3000:]
