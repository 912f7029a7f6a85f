"""``muble eval``: an agent over every stored episode of a dataset split, executed with physics.

    muble eval agent=oracle dataset.root=/data/shopvrb2                     # split val, no rendering
    muble eval agent=random dataset.root=/data/shopvrb2 'dataset.splits=[test]' dataset.workers=8
    muble eval agent=oracle dataset.root=... evaluation.render=true renderer=mujoco renderer.width=320
    muble eval agent=oracle dataset.scenes_file=SCENES.json dataset.instructions_file=INSTRUCTIONS.json

The last form evaluates on files in the original SHOP-VRB2 layout (``muble.evaluation.files``): one episode per
instruction, on the scene with its ``image_filename``/``image_index``, reported as one split named after the
instruction file.

Writes under the run's output folder: ``episodes_<split>.jsonl`` (one result per index, appended as each episode
finishes), ``report.json`` (success per task type with its 95% interval, efficiency, failure taxonomy, the entries
with bad data, timing, manifest; an agent's counters with their cost and latency, and its price table),
``results.json`` (the versioned results file runs are shared and compared in, ``muble.evaluation.results``),
``success_<split>.png`` and ``summary.md``; the results table of each split is printed. Every output names the
protocol, track and observation mode the run followed (``benchmark.*``). Every index the dataset records gets an
outcome, unreadable files included (``invalid_data``). A run into a folder that holds an interrupted evaluation
with the same settings (``hydra.run.dir=DIR``) resumes it.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any, cast

from omegaconf import DictConfig, OmegaConf

from muble.app.hydra_app import run_hydra_job
from muble.app.plan import resolve
from muble.core.errors import ConfigError
from muble.dataset.executors import run_all
from muble.dataset.production import cached_components
from muble.dataset.protocol import check_data
from muble.evaluation.episodes import EvalJob, evaluate_index
from muble.evaluation.files import check_files, uses_files
from muble.evaluation.plot import success_bar_chart
from muble.evaluation.report import (OVERALL, bad_entry_table, failure_table, markdown, partial_split, partial_words,
                                     run_stamp, success_table, summarize)
from muble.evaluation.results import RESULTS_FILE, results_document
from muble.evaluation.resume import RECORDS, EpisodeLog, claim_folder, run_settings
from muble.evaluation.split import SplitIndices, check_split
from muble.evaluation.usage import PriceTable
from muble.io.atomic import write_bytes_atomic
from muble.io.layout import DatasetLayout
from muble.io.manifest import make_manifest, sha256_file

log = logging.getLogger(__name__)


def check_config(cfg: DictConfig) -> Path:
    """The dataset root, after checking what would otherwise fail deep inside a worker."""
    from muble.plugins.registry import get_registry

    registry = get_registry()
    if cfg.agent.name not in registry.names("agent"):
        raise ConfigError(f"unknown agent '{cfg.agent.name}'; set agent= to one of: "
                          f"{', '.join(registry.names('agent'))}")
    if uses_files(cfg.dataset):
        return Path(cfg.dataset.instructions_file).parent
    root = Path(cfg.dataset.root)
    if not root.is_dir():
        raise ConfigError(f"dataset folder {root} does not exist; set dataset.root= to a folder written by "
                          "`muble generate`" + ("" if cfg.benchmark.protocol else _protocol_hint()))
    if not list(cfg.dataset.splits):
        raise ConfigError("dataset.splits is empty; name the split(s) to evaluate, e.g. 'dataset.splits=[val]'")
    if cfg.evaluation.limit < 0:
        raise ConfigError(f"evaluation.limit must be >= 0 (0 = every index), got {cfg.evaluation.limit}")
    return root


def _protocol_hint() -> str:
    """How to evaluate the frozen benchmark instead, with no dataset at all (its splits ship with MuBlE)."""
    from muble.dataset.protocol import protocol_names
    from muble.dataset.shipped import newest_protocol

    newest = newest_protocol()
    if newest is None:
        return ""
    return (f", or evaluate a frozen benchmark's shipped episodes with no dataset: protocol={newest} "
            f"(benchmark.split=mini, the default; protocols: {', '.join(protocol_names())})")


def benchmark_stamp(cfg: DictConfig) -> dict[str, Any]:
    """What the run followed, as plain values: ``protocol`` (None without one), ``protocol_split`` (the protocol's
    split; None without a protocol, where ``benchmark.split`` means nothing), ``track`` and ``mode``."""
    from muble.episode.components import benchmark_settings

    track, mode = benchmark_settings(cfg)
    protocol = cfg.benchmark.protocol
    return {"protocol": protocol, "protocol_split": cfg.benchmark.split if protocol else None, "track": track,
            "mode": mode}


def evaluate_split(cfg: DictConfig, config: dict[str, Any], found: SplitIndices,
                   out_dir: Path) -> list[dict[str, Any]]:
    """Every selected index of a split gets a record: those already in the split's record file are read back, the
    others run, each appended to the file as it finishes. Returns the records in index order."""
    from tqdm import tqdm
    from tqdm.contrib.logging import logging_redirect_tqdm

    indices = found.indices[:cfg.evaluation.limit] if cfg.evaluation.limit else found.indices
    wanted = set(indices)
    episodes = EpisodeLog(out_dir / RECORDS.format(split=found.split))
    done = {i: r for i, r in episodes.read().items() if i in wanted}
    # Drop what is not a complete record (a line cut short by a kill) before appending after it.
    episodes.rewrite(list(done.values()))
    jobs = [EvalJob(config, found.split, i) for i in indices if i not in done]
    if done:
        log.info("%s: %d of %d episodes already done in %s; running the other %d", found.split, len(done),
                 len(indices), episodes.path, len(jobs))
    with episodes, logging_redirect_tqdm():  # log lines are written above the bar, which stays whole
        for record in tqdm(run_all(cfg.dataset.executor, evaluate_index, jobs, cfg.dataset.workers,
                                   ray_address=cfg.dataset.ray_address),
                           total=len(jobs), desc=f"eval {found.split}", unit="episode", disable=None):
            log.debug("%s %d (%s): %s", found.split, record["index"], record["template"], record["outcome"])
            episodes.append(record)
            done[record["index"]] = record
    records = [done[i] for i in indices]
    episodes.rewrite(records)
    return records


def job(cfg: DictConfig) -> dict[str, Any]:
    # protocol=NAME: the split benchmark.split names, from a generated copy in dataset.root or the shipped files
    plan = resolve(cfg, files="read")
    cfg, protocol_split = plan.config, plan.split
    root = check_config(cfg)
    out_dir = Path(cfg.output.dir)
    config = cast(dict[str, Any], OmegaConf.to_container(cfg, resolve=True))  # a composed config is a mapping
    dataset_manifest = root / "manifest.json"
    dataset_sha: str | None
    if uses_files(cfg.dataset):
        # Original-format files: one split of every instruction in the instruction file.
        split, indices, dataset_sha = check_files(cfg.dataset)
        found = {split: SplitIndices(split, indices, source=str(cfg.dataset.instructions_file))}
        dataset = f"{cfg.dataset.scenes_file} + {cfg.dataset.instructions_file}"
    else:
        # Validate every split before running any episode: a typo in the last split should not cost an hour.
        found = {split: check_split(DatasetLayout(root, split)) for split in cfg.dataset.splits}
        dataset_sha = sha256_file(dataset_manifest) if dataset_manifest.is_file() else None
        dataset = str(root)
    protocol_data = None
    if protocol_split is not None:
        if uses_files(cfg.dataset):
            raise ConfigError("protocol= evaluates a protocol split written by `muble generate protocol=...`; "
                              "leave out dataset.scenes_file and dataset.instructions_file, or protocol=")
        # Results are labelled with the protocol only on its data: a differing hash stops here (exit 2).
        protocol_data = {k: v for k, v in check_data(cfg, root, protocol_split).items() if k != "files"}
    # The configured plugins (but a renderer) are built here once, so a bad option stops the run before any episode.
    cached_components(config, renderer=False, task=False)
    claim_folder(out_dir, run_settings(config, dataset_sha), list(found))
    stamp = benchmark_stamp(cfg)
    report: dict[str, Any] = {"agent": cfg.agent.name, "dataset": dataset, "protocol": stamp["protocol"],
                              "track": stamp["track"], "mode": stamp["mode"], "protocol_data": protocol_data,
                              "splits": {}}
    prices = PriceTable.of(config["agent"])
    if prices is not None:  # an agent that prices its model calls: every cost in the report is at this table
        report["prices"] = prices.as_dict()
    plots: dict[str, str] = {}
    written: dict[str, str] = {}
    split_records: dict[str, list[dict[str, Any]]] = {}
    for split in found:
        records = evaluate_split(cfg, config, found[split], out_dir)
        split_records[split] = records
        name = RECORDS.format(split=split)
        written[name] = sha256_file(out_dir / name)
        summary = summarize(records, list(cfg.dataset.templates))
        summary["skipped"] = found[split].skipped
        summary["indices_from"] = found[split].source
        summary["partial"] = partial_split(len(records), len(found[split].indices))
        report["splits"][split] = summary
        if cfg.evaluation.plot:
            rates = {t: s["success_rate"] for t, s in summary["templates"].items()}
            rates[OVERALL] = summary[OVERALL]["success_rate"]
            plots[split] = f"success_{split}.png"
            written[plots[split]] = write_bytes_atomic(
                out_dir / plots[split], success_bar_chart(rates, f"{cfg.agent.name} on {split}: success rate"))
        covered = f", {partial_words(summary['partial'])} (evaluation.limit)" if summary["partial"] else ""
        print(success_table(summary, f"agent {cfg.agent.name}, split {split}{covered} ({dataset}); "
                                     f"{run_stamp(stamp['protocol'], stamp['track'], stamp['mode'])}"))
        print()
        print(failure_table(summary))
        print()
        bad = bad_entry_table(summary)
        if bad:
            print(f"{len(summary['bad_entries'])} entries with bad data (counted in the rates above):")
            print(bad)
            print()
    written["summary.md"] = write_bytes_atomic(out_dir / "summary.md", markdown(report, plots).encode())
    seeds = {"seed": cfg.seed, "agent": config["agent"],
             "episodes": "stored scene + instruction per index; each worker replays them deterministically"}
    report["manifest"] = make_manifest(seeds, config, dataset_manifest_sha256=dataset_sha, files=written)
    # A protocol split is named by its data hash (the same on every machine); other data by its manifest's sha256.
    data_sha = protocol_data["data_sha256"] if protocol_data else dataset_sha
    run = {**stamp, "data_sha256": data_sha, "agent": cfg.agent.name, "agent_config": config["agent"],
           "seed": cfg.seed, "dataset": dataset}
    results = results_document(run=run, manifest=report["manifest"],
                               splits={split: (report["splits"][split], split_records[split]) for split in found})
    # ``written`` is the manifest's file list, so report.json lists results.json with its sha256 too.
    written[RESULTS_FILE] = write_bytes_atomic(out_dir / RESULTS_FILE,
                                               json.dumps(results, indent=2, sort_keys=True).encode())
    write_bytes_atomic(out_dir / "report.json", json.dumps(report, indent=2, sort_keys=True).encode())
    overall = {split: s[OVERALL]["success_rate"] for split, s in report["splits"].items()}
    print(f"muble eval: report in {out_dir / 'report.json'}; success rate "
          + ", ".join(f"{split} {100 * r:.1f}%" for split, r in overall.items()))
    return overall


def main(argv: list[str]) -> int:
    return run_hydra_job("eval", argv, job, prog="muble eval")
