"""``muble eval``: an agent over every stored episode of a dataset split, executed with physics.

    muble eval agent=oracle dataset.root=/data/shopvrb2                     # split val, no rendering
    muble eval agent=random dataset.root=/data/shopvrb2 'dataset.splits=[test]' dataset.workers=8
    muble eval agent=oracle dataset.root=... evaluation.render=true renderer=mujoco renderer.width=320

Writes under the run's output folder: ``episodes_<split>.jsonl`` (one result per index), ``report.json``
(success per task type, failure taxonomy, timing, manifest), ``success_<split>.png`` and ``summary.md``; the
results table of each split is printed.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from muble.app.hydra_app import run_hydra_job
from muble.core.errors import ConfigError
from muble.core.manifest import make_manifest, sha256_file
from muble.dataset.atomic import write_bytes_atomic
from muble.dataset.executors import run_all
from muble.dataset.layout import DatasetLayout
from muble.evaluation.episodes import EvalJob, check_split, evaluate_index
from muble.evaluation.plot import success_bar_chart
from muble.evaluation.report import OVERALL, failure_table, markdown, success_table, summarize

log = logging.getLogger(__name__)


def check_config(cfg: DictConfig) -> Path:
    """The dataset root, after checking what would otherwise fail deep inside a worker."""
    from muble.plugins.registry import get_registry

    registry = get_registry()
    if cfg.agent.name not in registry.names("agent"):
        raise ConfigError(f"unknown agent '{cfg.agent.name}'; set agent= to one of: "
                          f"{', '.join(registry.names('agent'))}")
    root = Path(cfg.dataset.root)
    if not root.is_dir():
        raise ConfigError(f"dataset folder {root} does not exist; set dataset.root= to a folder written by "
                          "`muble generate`")
    if not list(cfg.dataset.splits):
        raise ConfigError("dataset.splits is empty; name the split(s) to evaluate, e.g. 'dataset.splits=[val]'")
    if cfg.evaluation.limit < 0:
        raise ConfigError(f"evaluation.limit must be >= 0 (0 = every index), got {cfg.evaluation.limit}")
    return root


def evaluate_split(cfg: DictConfig, config: dict[str, Any], root: Path, split: str) -> list[dict[str, Any]]:
    from tqdm import tqdm

    layout = DatasetLayout(root, split)
    indices = check_split(layout)
    if cfg.evaluation.limit:
        indices = indices[:cfg.evaluation.limit]
    jobs = [EvalJob(config, split, i) for i in indices]
    records = []
    for record in tqdm(run_all(cfg.dataset.executor, evaluate_index, jobs, cfg.dataset.workers), total=len(jobs),
                       desc=f"eval {split}", unit="episode", disable=None):
        log.info("%s %d (%s): %s", split, record["index"], record["template"], record["outcome"])
        records.append(record)
    return sorted(records, key=lambda r: r["index"])


def job(cfg: DictConfig) -> dict[str, Any]:
    root = check_config(cfg)
    out_dir = Path(cfg.output.dir)
    config = OmegaConf.to_container(cfg, resolve=True)
    # Validate every split before running any episode: a typo in the last split should not cost an hour.
    for split in cfg.dataset.splits:
        check_split(DatasetLayout(root, split))
    dataset_manifest = root / "manifest.json"
    report: dict[str, Any] = {"agent": cfg.agent.name, "dataset": str(root), "splits": {}}
    plots: dict[str, str] = {}
    written: dict[str, str] = {}
    for split in cfg.dataset.splits:
        records = evaluate_split(cfg, config, root, split)
        name = f"episodes_{split}.jsonl"
        written[name] = write_bytes_atomic(out_dir / name, "".join(
            json.dumps(r, sort_keys=True) + "\n" for r in records).encode())
        summary = summarize(records, list(cfg.dataset.templates))
        report["splits"][split] = summary
        if cfg.evaluation.plot:
            rates = {t: s["success_rate"] for t, s in summary["templates"].items()}
            rates[OVERALL] = summary[OVERALL]["success_rate"]
            plots[split] = f"success_{split}.png"
            written[plots[split]] = write_bytes_atomic(
                out_dir / plots[split], success_bar_chart(rates, f"{cfg.agent.name} on {split}: success rate"))
        print(success_table(summary, f"agent {cfg.agent.name}, split {split} ({root})"))
        print()
        print(failure_table(summary))
        print()
    written["summary.md"] = write_bytes_atomic(out_dir / "summary.md", markdown(report, plots).encode())
    seeds = {"seed": cfg.seed, "agent": config["agent"],
             "episodes": "stored scene + instruction per index; each worker replays them deterministically"}
    report["manifest"] = make_manifest(
        seeds, config, dataset_manifest_sha256=sha256_file(dataset_manifest) if dataset_manifest.is_file() else None,
        files=written)
    write_bytes_atomic(out_dir / "report.json", json.dumps(report, indent=2, sort_keys=True).encode())
    overall = {split: s[OVERALL]["success_rate"] for split, s in report["splits"].items()}
    print(f"muble eval: report in {out_dir / 'report.json'}; success rate "
          + ", ".join(f"{split} {100 * r:.1f}%" for split, r in overall.items()))
    return overall


def main(argv: list[str]) -> int:
    return run_hydra_job("eval", argv, job, prog="muble eval")
