"""Checkpoints of the learned parts: weights beside the run's record, written atomically, resumable.

A checkpoint is one ``torch.save`` file holding ``format``, ``kind`` (planner, parser, recogniser), ``record`` (the
composed config, seeds, package versions and code revision of the run that made it, ``TrainingRun.record``),
``identity`` (what decides the result: the trainer's settings and the seed; a resumed run must match it),
``epoch`` (finished epochs), ``state`` (the model's and the optimiser's state dicts, the RNG states) and
``extra`` (vocabularies, figures). Agents load one with ``load`` and are told what is wrong with a file that is
not one.
"""
from __future__ import annotations

import os
import random
import tempfile
from pathlib import Path
from typing import Any, Iterable, Iterator

from muble.core.errors import ConfigError
from muble.core.training import TrainingRun

FORMAT = "muble-checkpoint/1"
# Settings of ``muble train`` that say how a run goes, not what it yields: left out of the identity.
_EXECUTION_KEYS = ("out_dir", "resume", "progress", "threads")


def torch_module():
    """``torch``, or a ``ConfigError`` that says how to install it."""
    try:
        import torch
    except ImportError as e:  # pragma: no cover - exercised only without the extra
        raise ConfigError("the learned parts need PyTorch: pip install 'muble[learn]'") from e
    return torch


def identity(run: TrainingRun, settings: dict[str, Any]) -> dict[str, Any]:
    """What decides a run's result: the trainer's settings, the seed and the training split's protocol."""
    train = (run.record.get("config") or {}).get("train") or {}
    return {"settings": settings, "seed": run.seed, "protocol": run.protocol,
            "data_root": str(run.data_root) if run.data_root else None,
            "train": {k: v for k, v in train.items() if k not in _EXECUTION_KEYS and k != "data_root"}}


def seed_everything(seed: int) -> None:
    """Seed Python's and torch's generators; torch uses deterministic kernels. (NumPy's global generator is left
    alone: every numpy draw of MuBlE comes from a named stream, ``muble.core.streams``.)"""
    torch = torch_module()
    random.seed(seed)
    torch.manual_seed(seed)
    torch.use_deterministic_algorithms(True, warn_only=True)


def set_threads(run: TrainingRun) -> None:
    if run.threads > 0:
        torch_module().set_num_threads(run.threads)


def rng_states() -> dict[str, Any]:
    return {"python": random.getstate(), "torch": torch_module().get_rng_state()}


def restore_rng(states: dict[str, Any]) -> None:
    """Python's and torch's generator states (a checkpoint's ``numpy`` state, written before every draw came from
    a named stream, is not needed)."""
    random.setstate(states["python"])
    torch_module().set_rng_state(states["torch"])


def save(path: str | Path, kind: str, run: TrainingRun, ident: dict[str, Any], epoch: int, state: dict[str, Any],
         extra: dict[str, Any] | None = None) -> Path:
    """Write a checkpoint atomically (a stopped write leaves the previous one in place)."""
    torch = torch_module()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {"format": FORMAT, "kind": kind, "record": run.record, "identity": ident, "epoch": epoch,
               "state": state, "extra": extra or {}}
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".pt", dir=path.parent)
    os.close(fd)
    try:
        torch.save(payload, tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def load(path: str | Path, kind: str) -> dict[str, Any]:
    """A checkpoint of ``kind``; ``ConfigError`` naming the problem for a missing, foreign or other-kind file."""
    torch = torch_module()
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"no {kind} checkpoint at '{path}'; train one with `muble train trainer={kind} "
                          f"train.out_dir=DIR` and give DIR/{kind}.pt")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as e:
        raise ConfigError(f"'{path}' is not a readable checkpoint ({type(e).__name__}: {e})") from e
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise ConfigError(f"'{path}' is not a MuBlE checkpoint (format {FORMAT} expected)")
    if payload.get("kind") != kind:
        raise ConfigError(f"'{path}' is a {payload.get('kind')} checkpoint, not a {kind} one")
    return payload


def resume_from(path: str | Path, kind: str, run: TrainingRun, ident: dict[str, Any]) -> dict[str, Any] | None:
    """The checkpoint to go on from, or None to start afresh (none there, or ``run.resume`` off). One made under
    other settings is refused: mixing two runs would make a checkpoint neither config describes."""
    path = Path(path)
    if not run.resume or not path.is_file():
        return None
    payload = load(path, kind)
    if payload["identity"] != ident:
        raise ConfigError(f"'{path}' was trained under other settings; give another train.out_dir, or "
                          "train.resume=false to start this one over")
    return payload


def restore(payload: dict[str, Any], model: Any, optimiser: Any, schedule: Any = None) -> int:
    """Load a checkpoint's model, optimiser (and learning-rate schedule) and RNG states; its finished epochs."""
    model.load_state_dict(payload["state"]["model"])
    optimiser.load_state_dict(payload["state"]["optimiser"])
    if schedule is not None:
        schedule.load_state_dict(payload["state"]["schedule"])
    restore_rng(payload["state"]["rng"])
    return int(payload["epoch"])


def progress(items: Iterable, run: TrainingRun, desc: str, total: int | None = None) -> Iterator:
    """``items`` with a progress bar on stderr when the run shows one."""
    if not run.progress:
        yield from items
        return
    from tqdm import tqdm

    yield from tqdm(items, desc=desc, total=total, leave=False, dynamic_ncols=True)
