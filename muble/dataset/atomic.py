"""Atomic file output, re-exported from ``muble.core.atomic`` (where it lives: the core writes files too)."""
from muble.core.atomic import (TMP_PREFIX, check_output_folder, current_umask, file_mode, folder_mode,
                               remove_stale_temporaries, staged_folder, write_bytes_atomic)

__all__ = ["TMP_PREFIX", "check_output_folder", "current_umask", "file_mode", "folder_mode",
           "remove_stale_temporaries", "staged_folder", "write_bytes_atomic"]
