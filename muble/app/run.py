"""``muble run``: one SHOP-VRB2 episode on the configured robot, renderer, planner, task, objects and agent."""
from __future__ import annotations

import json
import logging
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from muble.app.config import GROUP_OF_KIND
from muble.app.hydra_app import run_hydra_job
from muble.core.manifest import make_manifest
from muble.core.scene_io import write_json_atomic
from muble.plugins.registry import get_registry

log = logging.getLogger(__name__)


def build_components(cfg: DictConfig) -> dict[str, object]:
    """Instantiate every configured plugin through the registry (a typo in any option fails here, early)."""
    registry = get_registry()
    components = {}
    for kind, group in GROUP_OF_KIND.items():
        node = cfg[group]
        components[kind] = registry.create(kind, node.name, node)
    components["sensors"] = [registry.create("sensor", name, options or {})
                             for name, options in cfg.sensors.enabled.items()]
    return components


def job(cfg: DictConfig) -> dict:
    out_dir = Path(cfg.output.dir)
    components = build_components(cfg)
    manifest = make_manifest({"seed": cfg.seed, "scene_index": cfg.scene_index},
                             OmegaConf.to_container(cfg, resolve=True))
    write_json_atomic(out_dir / "manifest.json", manifest, indent=2)
    summary = {kind: type(c).__name__ for kind, c in components.items() if kind != "sensors"}
    if cfg.dry_run:
        print(f"muble run: dry run; built {', '.join(f'{k}={v}' for k, v in summary.items())}; "
              f"manifest in {out_dir}")
        return summary
    log.info("components: %s", json.dumps(summary))
    print(f"muble run: built {', '.join(f'{k}={v}' for k, v in summary.items())}; manifest in {out_dir}")
    return summary


def main(argv: list[str]) -> int:
    return run_hydra_job("run", argv, job, prog="muble run")
