"""Atomic file output: write to a temporary file in the same folder, fsync, rename. Readers never see a
partial file, and a killed writer leaves only a hidden temporary that the next run removes."""
from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

TMP_PREFIX = ".muble-tmp-"


def write_bytes_atomic(path: str | Path, data: bytes) -> str:
    """Write ``data`` to ``path`` atomically; returns its sha256."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=TMP_PREFIX)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return hashlib.sha256(data).hexdigest()


def remove_stale_temporaries(root: str | Path) -> int:
    """Delete temporaries a killed run left behind; returns how many."""
    count = 0
    for p in Path(root).rglob(f"{TMP_PREFIX}*"):
        p.unlink(missing_ok=True)
        count += 1
    return count
