"""Hydra callbacks of MuBlE's jobs."""
from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any, ClassVar

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

log = logging.getLogger(__name__)


class SweepSummary(Callback):
    """After a multirun, one line per configuration (its overrides and outcome) and ``summary.json``.

    ``current`` is the sweep folder of the multirun in progress (None outside one), so that a multirun that
    fails on a usage error before its first job can remove the folder Hydra made for it."""

    current: ClassVar[Path | None] = None

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        SweepSummary.current = Path(config.hydra.sweep.dir)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        SweepSummary.current = None
        rows = []
        for manifest_path in sorted(sweep_dir.glob("*/manifest.json"), key=lambda p: int(p.parent.name)
                                    if p.parent.name.isdigit() else 0):
            job_dir = manifest_path.parent
            overrides_file = job_dir / ".hydra" / "overrides.yaml"
            overrides = " ".join(OmegaConf.load(overrides_file)) if overrides_file.exists() else ""
            manifest = json.loads(manifest_path.read_text())
            rows.append({"job": job_dir.name, "overrides": overrides, "outcome": manifest.get("outcome", "dry-run")})
        if not rows:
            return
        (sweep_dir / "summary.json").write_text(json.dumps(rows, indent=2))
        width = max(len(r["overrides"]) for r in rows)
        print(f"\nsweep summary ({sweep_dir}):")
        for r in rows:
            print(f"  {r['job']:>3}  {r['overrides']:<{width}}  {r['outcome']}")
