"""``muble train``: train one learned part with a registered trainer (``muble.core.interfaces.Trainer``).

    muble train trainer=planner train.out_dir=runs/planner             # the learned planner (symbolic roll-outs)
    muble train trainer=parser train.out_dir=runs/parser               # instruction text -> program
    muble train trainer=recogniser train.out_dir=runs/recogniser       # object crop -> attributes
    muble train trainer=planner trainer.scenes=50 trainer.epochs=1     # a quick round trip

Deterministic from ``seed``; every checkpoint records the composed config and the code version; running again
into the same ``train.out_dir`` goes on from its last checkpoint (``train.resume=false`` starts over). The
figures the trainer returns are printed and written to ``train.json`` in the output folder.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any, cast

from omegaconf import DictConfig, OmegaConf

from muble.app.hydra_app import run_hydra_job
from muble.core.errors import ConfigError
from muble.core.training import TrainingRun
from muble.io.atomic import write_bytes_atomic
from muble.io.manifest import make_manifest
from muble.plugins.registry import get_registry

log = logging.getLogger(__name__)


def _checks(cfg: DictConfig) -> None:
    if cfg.trainer is None or "name" not in cfg.trainer:
        names = ", ".join(get_registry().names("trainer")) or "none registered"
        raise ConfigError(f"muble train needs trainer=NAME; registered trainers: {names}")
    if cfg.train.data_root is not None and not Path(cfg.train.data_root).is_dir():
        raise ConfigError(f"train.data_root={cfg.train.data_root!r} is not a folder; give the root of a dataset "
                          "written by `muble generate`")


def training_run(cfg: DictConfig) -> TrainingRun:
    """The ``TrainingRun`` a composed ``train`` config describes."""
    config = cast(dict[str, Any], OmegaConf.to_container(cfg, resolve=True))  # a composed config is a mapping
    record = make_manifest({"seed": int(cfg.seed)}, {k: v for k, v in config.items() if k not in ("output",)})
    protocol = config.get("protocol")
    return TrainingRun(out_dir=Path(cfg.train.out_dir or cfg.output.dir), seed=int(cfg.seed), resume=bool(cfg.train.resume),
                       record=record, progress=bool(cfg.train.progress), protocol=protocol,
                       data_root=Path(cfg.train.data_root) if cfg.train.data_root else None,
                       threads=int(cfg.train.threads))


def _job(cfg: DictConfig) -> int:
    trainer = get_registry().create("trainer", cfg.trainer.name, cfg.trainer)
    run = training_run(cfg)
    run.out_dir.mkdir(parents=True, exist_ok=True)
    figures = trainer.train(run)
    summary = {"trainer": cfg.trainer.name, "seed": run.seed, "out_dir": str(run.out_dir), "figures": figures,
               "git_revision": run.record.get("git_revision"), "versions": run.record.get("versions")}
    write_bytes_atomic(run.out_dir / "train.json", (json.dumps(summary, indent=2, default=str) + "\n").encode())
    for key, value in figures.items():
        print(f"{key}: {value:.4g}" if isinstance(value, float) else f"{key}: {value}")
    print(f"trained {cfg.trainer.name} into {run.out_dir}")
    return 0


def main(argv: list[str]) -> int:
    return run_hydra_job("train", argv, _job, prog="muble train", checks=_checks)
