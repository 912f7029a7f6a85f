"""``muble verify RUN``: replay an evaluation run's recorded decisions and say, per episode, whether the physics
went the same way.

No agent and no endpoint are asked: each episode's primitives (and its answer) come from its record and are sent
again, in order, under the run's stored settings (``eval_run.json``), disturbances and all. After every primitive
the world's fingerprint (``muble.episode.fingerprint``) is compared with the recorded one; the first primitive
whose fingerprint differs by more than the tolerance is reported, with the largest difference seen and whether the
outcome changed. Records made before fingerprints existed are replayed for their outcome only.
"""
from __future__ import annotations

import ast
import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from muble.core.errors import ConfigError
from muble.core.interfaces import Agent
from muble.core.types import ActionCall, Answer, ObservationMode, Track
from muble.episode.fingerprint import TOLERANCE, first_difference
from muble.evaluation.closed_loop import parse_action
from muble.evaluation.resume import RECORDS, RUN_FILE

log = logging.getLogger(__name__)


def action_of(text: str) -> ActionCall:
    """A record's primitive string (``str(ActionCall)``) as the call it was: values read as Python literals."""
    name, args = parse_action(text)
    params = {}
    for key, value in args.items():
        try:
            params[key] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            params[key] = value
    return ActionCall(name, params)


class ReplayAgent(Agent):
    """Sends a record's primitives in order, then its answer, then stops. Privileged like the oracle: it names
    objects by id, and the loop puts its calls in the mode's form (pixels in image mode) as it does the oracle's."""

    privileged = True

    def __init__(self, record: dict[str, Any]) -> None:
        self.calls = [action_of(p) for p in record.get("primitives") or []]
        self.answer = record.get("answer")
        self.sent = 0
        self.answered = False

    def reset(self, instruction, observation, *, track: Track = Track.program,
              mode: ObservationMode = ObservationMode.graph) -> None:
        self.sent, self.answered = 0, False

    def act(self, instruction, observation) -> ActionCall | Answer | None:
        if self.sent < len(self.calls):
            self.sent += 1
            return self.calls[self.sent - 1]
        if self.answer is not None and not self.answered:
            self.answered = True
            return Answer(self.answer)
        return None


@dataclass
class VerifyJob:
    """One episode to replay: the run's config (plain), its split and the stored record."""

    config: dict[str, Any]
    split: str
    record: dict[str, Any]
    tolerance: int = TOLERANCE


def verify_index(job: VerifyJob) -> dict[str, Any]:
    """Replay one record; what agrees and where it first differs."""
    from muble.dataset.production import IndexJob
    from muble.evaluation.episodes import evaluate_index

    stored = job.record
    again = evaluate_index(IndexJob(job.config, job.split, int(stored["index"])), agent=ReplayAgent(stored))
    recorded, replayed = stored.get("fingerprints"), again.get("fingerprints") or []
    out = {"index": stored["index"], "template": stored.get("template"), "outcome": stored.get("outcome"),
           "replayed_outcome": again.get("outcome"), "primitives": len(stored.get("primitives") or []),
           "fingerprinted": recorded is not None, "first_difference": None, "largest_difference": 0,
           "platform": again.get("platform"), "recorded_platform": stored.get("platform")}
    if recorded is not None:
        first, worst = first_difference(recorded, replayed, job.tolerance)
        out["largest_difference"] = worst
        if first is not None:
            primitives = stored.get("primitives") or []
            out["first_difference"] = {"fingerprint": first,
                                       "after": primitives[first - 1] if 0 < first <= len(primitives) else None}
    out["outcome_changed"] = out["outcome"] != out["replayed_outcome"]
    return out


def run_config(run: Path) -> dict[str, Any]:
    """The config an evaluation run's episodes ran under, from its stored settings; a protocol split's shipped files
    are found in this machine's cache (unpacked there if need be)."""
    path = run / RUN_FILE
    if not path.is_file():
        raise ConfigError(f"{run} holds no {RUN_FILE}: give the folder a `muble eval` run wrote (hydra.run.dir=...)")
    try:
        settings = json.loads(path.read_text(encoding="utf-8"))["settings"]
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as e:
        raise ConfigError(f"{path} is unreadable ({type(e).__name__}: {e})") from e
    config = {k: v for k, v in settings.items() if k != "dataset_manifest_sha256"}
    config.setdefault("output", {"dir": None})
    config.setdefault("generator", {})
    config["evaluation"] = {**config.get("evaluation", {}), "keyframes": False, "plot": False, "limit": 0}
    return config


def _dataset_root(config: dict[str, Any], split: str) -> None:
    from muble.dataset.protocol import load_protocol, shipped_archive, shipped_root

    name = (config.get("benchmark") or {}).get("protocol")
    if not name or Path(config["dataset"]["root"]).is_dir():
        return
    protocol = load_protocol(name)
    if shipped_archive(protocol, split) is not None:
        config["dataset"] = {**config["dataset"], "root": str(shipped_root(protocol, split).parent)}


def records_of(run: Path, split: str) -> list[dict[str, Any]]:
    path = run / RECORDS.format(split=split)
    if not path.is_file():
        raise ConfigError(f"{run} has no records of split '{split}' ({path.name})")
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]


def verify_run(run: Path, split: str | None = None, limit: int = 0, workers: int = 1,
               tolerance: int = TOLERANCE) -> dict[str, Any]:
    """Replay every record of ``run`` (of ``split``, or of each split it holds; the first ``limit``) and compare."""
    from muble.dataset.executors import run_all

    config = run_config(run)
    splits = [split] if split else list(config["dataset"].get("splits") or [])
    report: dict[str, Any] = {"run": str(run), "tolerance_units": tolerance, "splits": {}}
    for name in splits:
        _dataset_root(config, name)
        records = sorted(records_of(run, name), key=lambda r: r["index"])
        if limit:
            records = records[:limit]
        jobs = [VerifyJob(config, name, r, int(tolerance)) for r in records]
        results = sorted(run_all("processes" if workers > 1 else "serial", verify_index, jobs, workers),
                         key=lambda r: r["index"])
        report["splits"][name] = {
            "episodes": len(results),
            "agree": sum(r["fingerprinted"] and r["first_difference"] is None for r in results),
            "identical": sum(r["fingerprinted"] and r["largest_difference"] == 0 and r["first_difference"] is None
                             for r in results),
            "differ": sum(r["first_difference"] is not None for r in results),
            "outcomes_changed": sum(r["outcome_changed"] for r in results),
            "largest_difference": max((r["largest_difference"] for r in results), default=0),
            "episodes_detail": results,
        }
    return report
