"""Atomic file output: write to a temporary file in the same folder, fsync, rename. Readers never see a
partial file, and a killed writer leaves only a hidden temporary that the next run removes.

Files and folders get the mode the process's umask gives (0644/0755 under the usual 022), as ``open`` would,
not the private 0600/0700 of ``tempfile``: a dataset made for a team, or in a container under another uid, stays
readable. ``staged_folder`` writes a whole output folder the same way: its files reach the folder only when the
block that writes them succeeds, so a failed command leaves nothing behind.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterator

from muble.core.errors import ConfigError

TMP_PREFIX = ".muble-tmp-"


def current_umask() -> int:
    """The process's umask, read without changing it where Linux tells it (``/proc/self/status``)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)  # elsewhere: set and restore (not thread-safe, but only where /proc is missing)
    os.umask(mask)
    return mask


def file_mode() -> int:
    return 0o666 & ~current_umask()


def folder_mode() -> int:
    return 0o777 & ~current_umask()


def write_bytes_atomic(path: str | Path, data: bytes, *, replace: bool = True) -> str:
    """Write ``data`` to ``path`` atomically; returns its sha256.

    With ``replace=False`` a file already at ``path`` is never overwritten: the write raises
    ``FileExistsError`` and ``path`` keeps what it held (the temporary is linked into place, which fails where
    a file is; a store of write-once entries uses it). On any failure (a full disk included) the temporary is
    removed and ``path`` keeps what it held; an ``OSError`` names ``path`` even where the system call that failed
    (a write, an fsync) names no file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=TMP_PREFIX)
    try:
        with os.fdopen(fd, "wb") as f:
            os.fchmod(f.fileno(), file_mode())
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        if replace:
            os.replace(tmp, path)
        else:
            os.link(tmp, path)
    except BaseException as e:
        if isinstance(e, OSError) and e.filename in (None, tmp):
            raise OSError(e.errno, e.strerror or str(e), str(path)) from e
        raise
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return hashlib.sha256(data).hexdigest()


def remove_stale_temporaries(root: str | Path) -> int:
    """Delete temporaries a killed run left behind; returns how many."""
    count = 0
    for p in Path(root).rglob(f"{TMP_PREFIX}*"):
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)
        count += 1
    return count


def _nearest_existing(path: Path) -> Path:
    path = path.absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def check_output_folder(path: str | Path, what: str) -> Path:
    """Check, creating nothing, that ``path`` is or can become a writable folder; ``what`` names it in errors
    (``"--out"``, ``"dataset.root"``). Returns the path."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{what} {path} is a file, not a folder; pass a folder (it is created if missing)")
    anchor = _nearest_existing(path)
    if not anchor.is_dir():
        raise ConfigError(f"{what} {path} cannot be created: {anchor} is a file; pass a folder elsewhere")
    if not os.access(anchor, os.W_OK | os.X_OK):
        raise ConfigError(f"{what} {path} cannot be written: {anchor} is not writable by this user; pass a folder "
                          "you can write to")
    return path


@contextlib.contextmanager
def staged_folder(out: str | Path, what: str = "--out", replace: bool = False) -> Iterator[Path]:
    """A hidden temporary folder beside ``out`` to write into; when the block succeeds its contents move into
    ``out`` (created if missing; with ``replace``, ``out``'s old contents are removed first), when it fails the
    temporary folder is removed and ``out`` is untouched."""
    out = check_output_folder(out, what).absolute()
    anchor = _nearest_existing(out.parent)
    stage = Path(tempfile.mkdtemp(prefix=TMP_PREFIX, dir=anchor))
    try:
        yield stage
        _publish(stage, out, replace)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _publish(stage: Path, out: Path, replace: bool) -> None:
    for folder in [stage, *(p for p in stage.rglob("*") if p.is_dir())]:
        os.chmod(folder, folder_mode())
    if out.exists() and replace:
        old = Path(tempfile.mkdtemp(prefix=f"{TMP_PREFIX}old-", dir=out.parent))
        os.replace(out, old)  # onto an empty folder: allowed
        shutil.rmtree(old, ignore_errors=True)
    if not out.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        os.replace(stage, out)
        return
    for src in sorted(stage.rglob("*")):
        dest = out / src.relative_to(stage)
        if src.is_dir():
            dest.mkdir(exist_ok=True)
        else:
            os.replace(src, dest)
