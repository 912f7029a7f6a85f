"""``muble generate``: the SHOP-VRB2 dataset, sharded by scene index, resumable, locally or on Ray.

    muble generate dataset.splits='{val: 20}' dataset.root=/data/shopvrb2 dataset.workers=2
    muble generate dataset.executor=ray ...            # same code path on a private local Ray cluster
    muble generate dataset.executor=ray dataset.ray_address=HOST:6379 ...   # on an existing Ray cluster
"""
from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any, cast

from omegaconf import DictConfig, OmegaConf

from muble.app.hydra_app import run_hydra_job
from muble.core.errors import ConfigError
from muble.dataset.executors import run_all
from muble.dataset.identity import check_or_store_identity
from muble.dataset.lock import RunLock
from muble.dataset.production import IndexJob, produce_index, split_seed
from muble.app.plan import resolve
from muble.dataset.protocol import PROTOCOL_FILE, check_data, check_regenerates, protocol_of
from muble.io.atomic import TMP_PREFIX, remove_stale_temporaries, write_bytes_atomic
from muble.io.layout import DatasetLayout
from muble.io.manifest import make_manifest, sha256_file

log = logging.getLogger(__name__)

# Settings that say how a dataset was produced, not what it contains: left out of its manifest so that runs on
# different executors, worker counts or folders yield identical datasets.
_EXECUTION_KEYS = ("root", "executor", "workers", "shard", "num_shards", "ray_address")


def dataset_config_record(config: dict[str, Any]) -> dict[str, Any]:
    record = {k: v for k, v in config.items() if k not in ("output", "train", "trainer")}
    record["dataset"] = {k: v for k, v in config["dataset"].items() if k not in _EXECUTION_KEYS}
    return record


def split_sizes(cfg: DictConfig) -> dict[str, int]:
    ds = cfg.dataset
    if len(ds.splits) != len(ds.sizes) or any(n < 0 for n in ds.sizes):
        raise ConfigError(f"dataset.splits {list(ds.splits)} and dataset.sizes {list(ds.sizes)} need one "
                          "non-negative size per split")
    if not 0 <= ds.shard < ds.num_shards:
        raise ConfigError(f"dataset.shard must be in [0, {ds.num_shards}), got {ds.shard}")
    return dict(zip(ds.splits, (int(n) for n in ds.sizes)))


def indices(cfg: DictConfig, size: int) -> list[int]:
    ds = cfg.dataset
    return [i for i in range(ds.start, ds.start + size) if i % ds.num_shards == ds.shard]


def write_combined(layout: DatasetLayout, wanted: list[int], version: str) -> dict[str, str]:
    """The combined ``{info, scenes}`` and ``{info, instructions}`` files of a split, in index order."""
    info = {"version": version, "split": layout.split}
    out = layout.split_dir
    scenes = [json.loads((out / layout.scene(i)).read_text()) for i in wanted]
    records = [json.loads((out / layout.instruction(i)).read_text()) for i in wanted]
    instructions = [r for r in records if r.get("instruction") is not None]
    return {
        layout.combined_scenes(): write_bytes_atomic(out / layout.combined_scenes(),
                                                     json.dumps({"info": info, "scenes": scenes}).encode()),
        layout.combined_instructions(): write_bytes_atomic(
            out / layout.combined_instructions(), json.dumps({"info": info, "instructions": instructions}).encode()),
    }


def checksums(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): sha256_file(p) for p in sorted(root.rglob("*"))
            if p.is_file() and p.name != "manifest.json" and not p.name.startswith(TMP_PREFIX)
            and p.suffix != ".lock"}


def lock_path(cfg: DictConfig) -> Path:
    """One lock per shard: shards of one dataset may run side by side, two runs of one shard may not."""
    return Path(cfg.dataset.root) / f".muble-generate-shard{cfg.dataset.shard}of{cfg.dataset.num_shards}.lock"


SPLITS_FILE = "dataset_splits.json"  # the sharding and each split's size the dataset was made with


def check_or_store_layout(root: Path, cfg: DictConfig, sizes: dict[str, int]) -> dict[str, int]:
    """Refuse a resume that would change the sharding or shrink a split (its combined file would silently lose the
    indices past the new size); a split may grow (extending a dataset). Returns every split's size, the stored
    ones included, and records them."""
    path = root / SPLITS_FILE
    stored: dict[str, Any] = {"num_shards": int(cfg.dataset.num_shards), "splits": {}}
    if path.is_file():
        try:
            stored = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise ConfigError(f"{path} cannot be read ({e}; truncated?); restore it or pass another dataset.root") \
                from e
    problems = []
    if int(stored.get("num_shards", cfg.dataset.num_shards)) != int(cfg.dataset.num_shards):
        problems.append(f"dataset.num_shards: stored {stored['num_shards']}, requested {cfg.dataset.num_shards}")
    for split, size in sizes.items():
        before = stored.get("splits", {}).get(split)
        if before is not None and size < before:
            problems.append(f"split {split}: stored size {before}, requested {size} (it would leave out indices "
                            f"{cfg.dataset.start + size} to {cfg.dataset.start + before - 1})")
    if problems:
        raise ConfigError(f"dataset.root {root} was made with other sharding or larger splits ({'; '.join(problems)})."
                          f" Resume with its settings (recorded in {SPLITS_FILE}), or pass another dataset.root")
    merged = {**stored.get("splits", {}), **sizes}
    write_bytes_atomic(path, json.dumps({"num_shards": int(cfg.dataset.num_shards), "splits": merged},
                                        indent=2, sort_keys=True).encode())
    return merged


def job(cfg: DictConfig) -> dict:
    """Produce the configured splits; a run that fails before producing anything leaves no folder it made."""
    root = Path(cfg.dataset.root)
    fresh = not root.exists() or not any(root.iterdir())
    try:
        return _job(cfg, root)
    except BaseException:
        if fresh and root.is_dir() and not any(p.is_dir() for p in root.iterdir()):
            import shutil

            shutil.rmtree(root, ignore_errors=True)  # only its settings and lock files: nothing to resume
        raise


def _job(cfg: DictConfig, root: Path) -> dict:
    from tqdm import tqdm
    from tqdm.contrib.logging import logging_redirect_tqdm

    import muble

    plan = resolve(cfg, files="write")  # protocol=NAME: the split benchmark.split names, at its frozen size
    cfg, protocol_split = plan.config, plan.split
    protocol = protocol_of(cfg)
    if protocol is not None:  # the plan has a protocol split exactly when the config follows a protocol
        check_regenerates(protocol)
    sizes = split_sizes(cfg)
    root.mkdir(parents=True, exist_ok=True)
    config = cast(dict[str, Any], OmegaConf.to_container(cfg, resolve=True))  # a composed config is a mapping
    with RunLock(lock_path(cfg), f"dataset.root {root} (shard {cfg.dataset.shard})"):
        check_or_store_identity(root, config)  # a resume with other settings is refused before any change
        recorded = check_or_store_layout(root, cfg, sizes)
        stale = remove_stale_temporaries(root)
        if stale:
            log.info("removed %d partial files of an interrupted run", stale)
        work = {}  # split -> (its layout, the indices this run holds, those still to produce)
        for split, size in sizes.items():
            layout, wanted = DatasetLayout(root, split), indices(cfg, size)
            todo = [i for i in wanted if not (layout.split_dir / layout.instruction(i)).exists()]
            work[split] = (layout, wanted, todo)
        # A previous run's manifest stays until this run writes its own (atomically), so an interruption or a full
        # disk leaves the description of what the last finished run wrote.
        produced = {}
        for split, (layout, wanted, todo) in work.items():
            log.info("%s: %d of %d indices to produce (%d already done)", split, len(todo), len(wanted),
                     len(wanted) - len(todo))
            jobs = [IndexJob(config, split, i) for i in todo]
            results = run_all(cfg.dataset.executor, produce_index, jobs, cfg.dataset.workers,
                              ray_address=cfg.dataset.ray_address)
            bar = tqdm(results, total=len(jobs), desc=f"generate {split}", unit="scene", disable=None)
            with logging_redirect_tqdm():  # log lines are written above the bar, which stays whole
                for done, (index, _) in enumerate(bar, start=1):
                    log.info("%s: index %d written (%d/%d)", split, index, done, len(jobs))
            if cfg.dataset.num_shards == 1:
                # Every index the split holds, those of a larger earlier run included.
                write_combined(layout, indices(cfg, recorded[split]), muble.__version__)
            produced[split] = len(wanted)
        seeds = {"seed": cfg.seed, "split_seeds": {s: split_seed(cfg.seed, s) for s in sizes},
                 "indices": "(split seed, index) -> named random streams (muble.core.streams); "
                            "OMPL re-seeded per query"}
        manifest = make_manifest(seeds, dataset_config_record(config), files=checksums(root))
        write_bytes_atomic(root / "manifest.json", json.dumps(manifest, indent=2, sort_keys=True).encode())
    print(f"muble generate: {produced} scenes in {root}")
    if protocol_split is not None and cfg.dataset.num_shards == 1:
        stamp = check_data(cfg, root, protocol_split)  # a recorded hash that differs is an error (exit 2)
        write_bytes_atomic(root / PROTOCOL_FILE.format(split=protocol_split),
                           json.dumps(stamp, indent=2, sort_keys=True).encode())
        verdict = {True: "matches the recorded hash", None: "no hash recorded for this split"}[stamp["matches"]]
        print(f"protocol {stamp['protocol']} split {protocol_split}: data sha256 {stamp['data_sha256']} ({verdict})")
    return produced


def check_root(cfg: DictConfig) -> None:
    """Refuse a ``dataset.root`` that is a file or cannot be written, before anything is created."""
    from muble.io.atomic import check_output_folder

    check_output_folder(cfg.dataset.root, "dataset.root")


def main(argv: list[str]) -> int:
    return run_hydra_job("generate", argv, job, prog="muble generate", checks=check_root)
