"""Usage errors: every mistake on a command line ends in one paragraph on stderr and exit code 2.

Hydra reports its own config errors (an unknown option, a mistyped key, a value of the wrong type, bad override
syntax) with exit code 1 and a message that does not always say what is valid. ``hydra_usage_errors`` puts them
under the project's rule: the same exit code as a ``MubleError``, the valid keys or options listed, the closest
ones suggested (names are case-sensitive: ``robot=panda`` suggests ``Panda``). ``HYDRA_FULL_ERROR=1`` still
gives Hydra's full traceback.
"""
from __future__ import annotations

import contextlib
import os
import sys
from typing import Any, Callable, Iterator

from muble.core.errors import suggest

USAGE_EXIT_CODE = 2

# Config options stored only as schemas for yaml files to extend, never selected by hand.
_SCHEMA_SUFFIX = "_schema"


def _first_line(text: Any) -> str:
    """The first line of a message, without a final full stop (the caller ends the sentence)."""
    lines = str(text).strip().splitlines()
    return lines[0].rstrip(".") if lines else ""


def _missing_config(ex: Any) -> str:
    missing = ex.missing_cfg_file or ""
    group, _, name = missing.rpartition("/")
    options = sorted(o for o in (ex.options or []) if not o.endswith(_SCHEMA_SUFFIX))
    if not group:
        return f"no config named '{missing}'; " + _first_line(str(ex))
    listing = ", ".join(options) if options else "(none)"
    return (f"unknown {group} option '{name}'{suggest(name, options)}; valid {group} options: {listing}. "
            f"Select one with {group}=NAME.")


def _unknown_key(cause: Any) -> str:
    from omegaconf import DictConfig

    full_key = str(cause.full_key or cause.key)
    parent_path, _, key = full_key.rpartition(".")
    parent = cause.parent_node
    valid = sorted(str(k) for k in parent.keys()) if isinstance(parent, DictConfig) else []
    valid = [k for k in valid if not (k == "hydra" and not parent_path)]
    where = f"keys of {parent_path}" if parent_path else "top-level keys"
    prefix = f"{parent_path}." if parent_path else ""
    message = f"unknown key '{full_key}'{suggest(key, valid, prefix)}; valid {where}: {', '.join(valid) or '(none)'}."
    if isinstance(parent, DictConfig) and cause.object_type in (dict, None):
        message += f" {parent_path or 'The config'} takes new entries: add one with +{full_key}=VALUE."
    return message


def environment_error(ex: OSError) -> str:
    """One paragraph naming an environment failure (a full disk, a folder that cannot be written, a path that is
    a file) and what to change; these are the machine's state, not bugs, so no traceback."""
    import errno

    name = str(ex.filename) if getattr(ex, "filename", None) else ""
    where = f" {_shortened(name)}" if name else ""
    reason = ex.strerror or str(ex)[:300]
    if ex.errno == errno.ENOSPC:
        advice = (f"{_full_disk(name)}: free space on it (or point the output elsewhere) and run the same command "
                  "again; `muble generate` and `muble eval` carry on from what was written")
    elif ex.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        advice = "that folder cannot be written: choose a writable one (dataset.root=, output.dir=, hydra.run.dir=)"
    elif ex.errno in (errno.EEXIST, errno.ENOTDIR):
        advice = "a file stands where a folder is needed: choose another path"
    elif ex.errno == errno.ENOENT:
        advice = "a folder on that path does not exist and cannot be made (is HOME or the parent folder set?)"
    elif ex.errno == errno.ENAMETOOLONG:
        advice = "the path is too long: choose a shorter one"
    else:
        advice = "check the path and the machine's state"
    return f"environment: cannot use{where}: {reason}; {advice}"


def _shortened(path: str) -> str:
    """A path as a message shows it: one of 10,000 characters by its ends."""
    return f"{path[:60]}…{path[-40:]} ({len(path)} characters)" if len(path) > 120 else path


def _full_disk(path: str) -> str:
    """``the disk holding FOLDER (mounted at M, N MB free of T MB) is full``, as much of it as can be found."""
    import shutil

    if not path:
        return "the disk is full"
    folder = os.path.abspath(path)
    while not os.path.isdir(folder) and os.path.dirname(folder) != folder:
        folder = os.path.dirname(folder)
    mount = folder
    while not os.path.ismount(mount):
        mount = os.path.dirname(mount)
    where = f"the disk holding {_shortened(folder)} (mounted at {_shortened(mount)}"
    try:
        usage = shutil.disk_usage(folder)
    except OSError:
        return f"{where}) is full"
    return f"{where}, {_size(usage.free)} free of {_size(usage.total)}) is full"


def _size(n: int) -> str:
    return f"{n / 1e9:.1f} GB" if n >= 1e9 else f"{n / 1e6:.1f} MB" if n >= 1e6 else f"{n / 1e3:.0f} kB"


def explain_config_error(ex: BaseException) -> str | None:
    """One paragraph saying what to change for a Hydra or OmegaConf config error; None for anything else."""
    from hydra.errors import ConfigCompositionException, HydraException, MissingConfigException
    from hydra.errors import OverrideParseException
    from omegaconf.errors import (ConfigAttributeError, ConfigKeyError, MissingMandatoryValue,
                                  OmegaConfBaseException, ValidationError)

    cause = ex.__cause__
    if isinstance(ex, MissingConfigException):
        return _missing_config(ex)
    if isinstance(ex, OverrideParseException):
        return (f"cannot parse the override '{ex.override}': {_first_line(ex.message)}. Overrides are KEY=VALUE, "
                "GROUP=OPTION, +KEY=VALUE (a new key) or ~KEY (remove); quote lists and strings with spaces "
                "for the shell, e.g. 'dataset.splits=[val,test]'.")
    for error in (ex, cause):
        if isinstance(error, (ConfigAttributeError, ConfigKeyError)) and getattr(error, "key", None) is not None:
            return _unknown_key(error)
        if isinstance(error, MissingMandatoryValue):
            key = getattr(error, "full_key", None) or "a value"
            return f"{key} has no value (???): set it on the command line, e.g. {key}=VALUE."
        if isinstance(error, ValidationError):
            key = getattr(error, "full_key", None) or getattr(error, "key", None)
            return f"invalid value for {key}: {_first_line(getattr(error, 'msg', error))}."
    if isinstance(ex, (ConfigCompositionException, HydraException)):
        detail = f" ({_first_line(cause)})" if isinstance(cause, OmegaConfBaseException) else ""
        return _first_line(str(ex)) + detail
    if isinstance(ex, OmegaConfBaseException):
        return _first_line(getattr(ex, "msg", None) or str(ex))
    if isinstance(ex, OSError):  # Hydra making the run folder, writing its files
        return environment_error(ex)
    if isinstance(ex, (ValueError, OverflowError, RecursionError)) and not isinstance(ex, OmegaConfBaseException):
        # Raised while the command line is parsed and composed (e.g. an integer of 10,000 digits): its fault.
        return f"cannot use the command line: {_first_line(ex)[:300]}"
    return None


def report(prog: str, message: str) -> None:
    print(f"{prog}: error: {message}", file=sys.stderr)


@contextlib.contextmanager
def hydra_usage_errors(prog: str, in_job: Callable[[], bool],
                       cleanup: Callable[[], None] = lambda: None) -> Iterator[None]:
    """While active, a config error Hydra would report with exit code 1 is reported by ``explain_config_error``
    and exits with ``USAGE_EXIT_CODE`` after ``cleanup()``. Errors raised while ``in_job()`` is true are the
    job's, left alone."""
    import hydra._internal.utils as hydra_utils

    original = hydra_utils.run_and_report

    def run_and_report(func: Callable[[], Any]) -> Any:
        def guarded() -> Any:
            try:
                return func()
            except Exception as ex:
                message = None if in_job() or os.environ.get("HYDRA_FULL_ERROR") == "1" \
                    else explain_config_error(ex)
                if message is None:
                    raise
                report(prog, message)
                cleanup()
                raise SystemExit(USAGE_EXIT_CODE) from ex

        return original(guarded)

    hydra_utils.run_and_report = run_and_report
    try:
        yield
    finally:
        hydra_utils.run_and_report = original
