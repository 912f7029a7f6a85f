"""Resumable evaluation: each finished episode is appended to its split's record file at once, and a run into a
folder that already holds records of the same evaluation carries on from them.

The folder keeps ``eval_run.json``: the settings that decide what an episode does (the agent, the dataset root
and its manifest, the splits, robot, planner, sensors, episode limits, seed …). A run into a folder whose stored
settings differ is refused, naming every difference; settings that only say how the work is executed or reported
(executor, workers, ``evaluation.limit``, ``evaluation.plot``, where outputs go) may change between runs, and
so may the renderer's settings of an evaluation that draws nothing (``evaluation.render=false`` in the ``graph``
mode, where no renderer is built).
"""
from __future__ import annotations

import json
import logging
import os
from pathlib import Path
from typing import IO, Any

from muble.core.errors import ConfigError
from muble.core.types import Outcome
from muble.dataset.identity import ABSENT, setting_differences
from muble.io.atomic import write_bytes_atomic

log = logging.getLogger(__name__)

RUN_FILE = "eval_run.json"
RECORDS = "episodes_{split}.jsonl"
_OUTCOMES = {o.value for o in Outcome}

# Settings free to change between runs into one folder: None = the whole section, else the keys within it.
_EXECUTION: dict[str, set[str] | None] = {
    "output": None,
    "dry_run": None,
    "scene_index": None,  # `muble run`'s; an evaluation takes its indices from the dataset
    "task": None,  # each instruction names its own template
    "generator": None,  # scenes come from the dataset's files
    "dataset": {"executor", "workers", "ray_address", "sizes", "start", "shard", "num_shards", "templates",
                "template_weights", "sequences", "gif"},
    "evaluation": {"limit", "plot"},
    "train": None,  # `muble train`'s own settings
    "trainer": None,
}


def draws(config: dict[str, Any]) -> bool:
    """Whether an evaluation builds a renderer: to record frames (``evaluation.render``) or because its observation
    mode shows the agent images (every mode but ``graph``)."""
    from muble.episode.components import benchmark_settings

    return bool(config["evaluation"]["render"]) or benchmark_settings(config)[1] != "graph"


def run_settings(config: dict[str, Any], dataset_manifest_sha256: str | None) -> dict[str, Any]:
    """The settings an evaluation's records depend on (the resolved config less execution-only keys; less the
    renderer's when nothing is drawn)."""
    settings: dict[str, Any] = {}
    for key, value in config.items():
        free = _EXECUTION.get(key, set())
        if free is None or (key == "renderer" and not draws(config)):
            continue
        settings[key] = {k: v for k, v in value.items() if k not in free} if free else value
    settings["dataset_manifest_sha256"] = dataset_manifest_sha256
    return settings


def differences(stored: Any, current: Any, where: str = "") -> list[str]:
    """Each setting that differs, as ``key: stored -> now``."""
    def show(value: Any) -> str:
        return "(absent)" if value is ABSENT else f"{value!r:.80}"

    return [f"{key}: {show(a)} -> {show(b)}" for key, a, b in setting_differences(stored, current, where)]


def claim_folder(out_dir: Path, settings: dict[str, Any], splits: list[str]) -> bool:
    """Make ``out_dir`` this evaluation's folder; returns True when it resumes an earlier run there.

    Raises ``ConfigError`` when the folder holds records of an evaluation with other settings (or of unknown
    settings), saying what differs and how to start afresh.
    """
    path = out_dir / RUN_FILE
    records = [out_dir / RECORDS.format(split=s) for s in splits]
    fresh = (f"evaluate into another folder (hydra.run.dir=DIR or output.dir=DIR), or delete {out_dir} to start "
             "again")
    if path.is_file():
        try:
            stored = json.loads(path.read_text(encoding="utf-8"))["settings"]
        except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as e:
            raise ConfigError(f"{path} is unreadable ({type(e).__name__}: {e}), so the records in {out_dir} cannot "
                              f"be resumed; {fresh}") from e
        if "renderer" not in settings and isinstance(stored, dict):
            stored = {k: v for k, v in stored.items() if k != "renderer"}  # kept by runs before it was left out
        # Round-trip through JSON so tuples and lists compare equal.
        diff = differences(stored, json.loads(json.dumps(settings)))
        if diff:
            raise ConfigError(f"{out_dir} holds an evaluation with other settings (stored -> now): "
                              + "; ".join(diff) + f". Resume with the stored settings, or {fresh}")
        log.info("resuming the evaluation in %s", out_dir)
        return True
    found = [p.name for p in records if p.is_file()]
    if found:
        raise ConfigError(f"{out_dir} holds episode records ({', '.join(found)}) without {RUN_FILE}, so it is unknown "
                          f"which settings made them; {fresh}")
    write_bytes_atomic(path, json.dumps({"settings": settings}, indent=2, sort_keys=True).encode())
    return False


def _valid(record: Any) -> bool:
    return (isinstance(record, dict) and isinstance(record.get("index"), int)
            and not isinstance(record["index"], bool) and record.get("outcome") in _OUTCOMES)


class EpisodeLog:
    """A split's ``episodes_<split>.jsonl``: one JSON line per finished episode, appended and flushed at once."""

    def __init__(self, path: Path):
        self.path = path
        self._file: IO[str] | None = None

    def read(self) -> dict[int, dict[str, Any]]:
        """The complete records in the file by index; a line cut short (a run killed mid-write) or malformed is
        left out, so its index runs again."""
        if not self.path.is_file():
            return {}
        done: dict[int, dict[str, Any]] = {}
        for n, line in enumerate(self.path.read_bytes().split(b"\n"), 1):
            if not line.strip():
                continue
            try:
                record = json.loads(line)
            except ValueError:
                log.warning("%s line %d is incomplete or not JSON; its episode runs again", self.path, n)
                continue
            if not _valid(record):
                log.warning("%s line %d is not an episode record; ignored", self.path, n)
                continue
            done[record["index"]] = record
        return done

    def rewrite(self, records: list[dict[str, Any]]) -> None:
        """Replace the file with ``records`` (in index order), atomically."""
        write_bytes_atomic(self.path, "".join(json.dumps(r, sort_keys=True) + "\n"
                                              for r in sorted(records, key=lambda r: r["index"])).encode())

    def __enter__(self) -> "EpisodeLog":
        self._file = open(self.path, "a", encoding="utf-8")
        return self

    def append(self, record: dict[str, Any]) -> None:
        """Write one finished episode and make sure it is on disk before the next one is reported."""
        assert self._file is not None, "use EpisodeLog as a context manager to append"
        self._file.write(json.dumps(record, sort_keys=True) + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())

    def __exit__(self, *exc: Any) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
