"""Running a MuBlE job as a Hydra application with the plugins' schemas and config folders in place."""
from __future__ import annotations

import logging
import sys
from typing import Any, Callable

import hydra
from omegaconf import DictConfig

from muble.app.config import CONFIG_MODULE, HYDRA_VERSION_BASE, register_configs, searchpath_override
from muble.core.errors import MubleError
from muble.plugins.registry import get_registry

log = logging.getLogger(__name__)


def run_hydra_job(config_name: str, argv: list[str], job: Callable[[DictConfig], Any], prog: str) -> int:
    """Run ``job`` under ``@hydra.main`` with ``argv`` as its command line; returns the exit code.

    Hydra itself exits non-zero for config errors (an unknown option lists the valid ones); a ``MubleError``
    raised by the job is reported in one line and exits with code 2.
    """
    registry = get_registry()
    register_configs(registry)
    extra = [] if any(a.startswith("hydra.searchpath") for a in argv) else searchpath_override(registry)

    @hydra.main(version_base=HYDRA_VERSION_BASE, config_path=f"pkg://{CONFIG_MODULE}", config_name=config_name)
    def _app(cfg: DictConfig) -> Any:
        try:
            return job(cfg)
        except MubleError as e:
            log.error("%s", e)
            print(f"{prog}: error: {e}", file=sys.stderr)
            raise SystemExit(2) from e

    saved = sys.argv
    sys.argv = [prog, *argv, *extra]
    try:
        _app()
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    finally:
        sys.argv = saved
    return 0
