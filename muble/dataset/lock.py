"""A lock file per dataset run, so that a restarted run never writes beside one still running.

The file holds the owner's pid, host and start time. A lock whose owner is gone (same host, and no such process
or a pid since reused by another process) is stale: it is taken over with a warning. A live owner, or one on
another host that cannot be checked, is refused with a message that says who holds it.
"""
from __future__ import annotations

import json
import logging
import os
import socket
import time
from pathlib import Path

from muble.core.errors import ConfigError

log = logging.getLogger(__name__)


def _start_ticks(pid: int) -> int | None:
    """When the process started (clock ticks after boot, Linux), to tell a reused pid from the owner."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        return int(stat.rsplit(")", 1)[1].split()[19])
    except (OSError, ValueError, IndexError):
        return None


def _owner_alive(pid: int, start_ticks: int | None) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # someone else's live process
    now = _start_ticks(pid)
    return start_ticks is None or now is None or now == start_ticks  # else the pid was reused


class RunLock:
    """``with RunLock(path, what):`` holds ``path`` for this process; ``what`` names the locked thing."""

    def __init__(self, path: str | Path, what: str):
        self.path, self.what = Path(path), what
        self.held = False

    def owner(self) -> dict | None:
        try:
            return json.loads(self.path.read_text())
        except (OSError, ValueError):
            return None

    def acquire(self) -> None:
        record = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%d %H:%M:%S"),
                  "start_ticks": _start_ticks(os.getpid())}
        for _ in range(2):
            try:
                fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
            except FileExistsError:
                self._refuse_or_break()
                continue
            with os.fdopen(fd, "w") as f:
                json.dump(record, f)
            self.held = True
            return
        raise ConfigError(f"{self.what} is locked by {self.path} and the lock could not be taken; remove it if no "
                          "run is using the folder")

    def _refuse_or_break(self) -> None:
        owner = self.owner() or {}
        pid, host = owner.get("pid"), owner.get("host")
        if isinstance(pid, int) and host == socket.gethostname() and not _owner_alive(pid, owner.get("start_ticks")):
            log.warning("%s: taking over the stale lock of process %s (no longer running)", self.what, pid)
            self.path.unlink(missing_ok=True)
            return
        if not owner:  # unreadable: being written right now, or left half-written by a crash long ago
            age = time.time() - self.path.stat().st_mtime if self.path.exists() else 0.0
            if age > 60:
                log.warning("%s: removing an unreadable lock file %s", self.what, self.path)
                self.path.unlink(missing_ok=True)
                return
        where = f"process {pid} on {host}" if host != socket.gethostname() else f"process {pid}"
        raise ConfigError(f"{self.what} is in use by {where} (since {owner.get('started', '?')}); wait for that run "
                          f"to finish or stop it, or remove {self.path} if it is gone (a lock from another host "
                          "cannot be checked from here)")

    def release(self) -> None:
        if self.held:
            owner = self.owner()
            if owner and owner.get("pid") == os.getpid():
                self.path.unlink(missing_ok=True)
            self.held = False

    def __enter__(self) -> "RunLock":
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
