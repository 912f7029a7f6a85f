"""Running a MuBlE job as a Hydra application with the plugins' schemas and config folders in place."""
from __future__ import annotations

import logging
import shutil
import sys
from pathlib import Path
from typing import Any, Callable

import hydra
from omegaconf import DictConfig, OmegaConf

from muble.app.config import CONFIG_MODULE, HYDRA_VERSION_BASE, register_configs, searchpath_override
from muble.app.usage import USAGE_EXIT_CODE, environment_error, explain_config_error, hydra_usage_errors, report
from muble.core.errors import MubleError
from muble.core.ranges import check_ranges
from muble.io.layout import check_split_name
from muble.plugins.registry import get_registry

log = logging.getLogger(__name__)

# What Hydra writes into a run folder before the job starts.
_HYDRA_BOOKKEEPING = (".hydra",)


def run_hydra_job(config_name: str, argv: list[str], job: Callable[[DictConfig], Any], prog: str,
                  checks: Callable[[DictConfig], None] | None = None) -> int:
    """Run ``job`` under ``@hydra.main`` with ``argv`` as its command line; returns the exit code.

    ``checks(cfg)`` runs after the schema checks and before the job, for what only this job requires (a
    writable output folder …); it raises ``MubleError`` to refuse the configuration.

    Every usage error exits with code 2 and one paragraph on stderr: Hydra's config errors (an unknown option or
    key lists the valid ones), values outside their schema's range, and any ``MubleError`` the job raises. A job
    that fails before writing anything leaves no run folder behind.
    """
    registry = get_registry()
    register_configs(registry)
    extra = [] if any(a.startswith("hydra.searchpath") for a in argv) else searchpath_override(registry)
    state = {"in_job": False}

    @hydra.main(version_base=HYDRA_VERSION_BASE, config_path=f"pkg://{CONFIG_MODULE}", config_name=config_name)
    def _app(cfg: DictConfig) -> Any:
        try:
            try:
                OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)
            except Exception as e:  # an unresolvable or missing value: the command line's fault
                message = explain_config_error(e)
                if message is None:
                    raise
                raise _Usage(message) from e
            check_ranges(cfg)
            check_choices()
            for split in cfg.dataset.splits:
                check_split_name(split)
            if checks is not None:
                checks(cfg)
            state["in_job"] = True
            try:
                return job(cfg)
            finally:
                state["in_job"] = False
        except (MubleError, _Usage) as e:
            _log_to_files(e)
            report(prog, str(e))
            _remove_empty_run_folder()
            raise SystemExit(USAGE_EXIT_CODE) from e
        except OSError as e:  # the machine's state (full disk, unwritable folder), not a bug: no traceback
            _log_to_files(e)
            report(prog, environment_error(e))
            _remove_empty_run_folder()
            raise SystemExit(USAGE_EXIT_CODE) from e

    saved = sys.argv
    sys.argv = [prog, *argv, *extra]
    try:
        with hydra_usage_errors(prog, lambda: state["in_job"], cleanup=_remove_empty_sweep_folder):
            _app()
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; run the same command again (with the same output folder) to carry on "
              "from what was written", file=sys.stderr)
        return INTERRUPTED_EXIT_CODE
    finally:
        sys.argv = saved
    return 0


INTERRUPTED_EXIT_CODE = 130  # 128 + SIGINT, as shells report it


class _Usage(Exception):
    """A config error found after composition (reported like a ``MubleError``)."""


def check_choices() -> None:
    """Refuse a ``*_schema`` option chosen by hand: schemas are what option yaml files extend, not options."""
    from hydra.core.hydra_config import HydraConfig

    for group, choice in HydraConfig.get().runtime.choices.items():
        if isinstance(choice, str) and choice.endswith("_schema") and not group.startswith("hydra"):
            top = group.split("@")[0]
            if "/" not in top and top != "_global_":
                raise _Usage(f"'{top}={choice}' selects a schema, not an option; choose one of the {top} options "
                             f"(`muble plugins` lists them), e.g. {top}={choice[:-len('_schema')]}")


def _log_to_files(error: BaseException) -> None:
    """The error into the run's log file only: stderr already has it, the console need not repeat it."""
    record = log.makeRecord(log.name, logging.ERROR, __file__, 0, "%s", (error,), None)
    for handler in logging.getLogger().handlers:
        if isinstance(handler, logging.FileHandler):
            handler.handle(record)


def _remove_empty_run_folder() -> None:
    """Remove the run folder Hydra made for this job if the job wrote nothing into it."""
    from hydra.core.hydra_config import HydraConfig

    try:
        hydra_cfg = HydraConfig.get()
    except ValueError:
        return
    out = Path(hydra_cfg.runtime.output_dir)
    log_file = out / f"{hydra_cfg.job.name}.log"
    if not out.is_dir() or any(p.name not in (*_HYDRA_BOOKKEEPING, log_file.name) for p in out.iterdir()):
        return
    for handler in logging.getLogger().handlers:
        if isinstance(handler, logging.FileHandler) and Path(handler.baseFilename) == log_file.resolve():
            logging.getLogger().removeHandler(handler)
            handler.close()
    shutil.rmtree(out, ignore_errors=True)


def _remove_empty_sweep_folder() -> None:
    """Remove a multirun's sweep folder if no job of it ran (Hydra writes ``multirun.yaml`` first)."""
    from muble.app.callbacks import SweepSummary

    sweep, SweepSummary.current = SweepSummary.current, None
    if sweep is not None and sweep.is_dir() and all(p.name == "multirun.yaml" for p in sweep.iterdir()):
        shutil.rmtree(sweep, ignore_errors=True)
