"""What a command runs, resolved once from its config into a frozen plan.

``muble eval``, ``muble generate`` and ``muble serve`` each turn the composed config into the same few decisions: the
protocol and its split (``benchmark.split``, at the split's frozen size), where the split's files are (a generated
copy in ``dataset.root``, or the files shipped with MuBlE), and the track and observation mode the episodes follow.
``resolve`` makes them once, checks them, and returns a ``RunPlan``: the decisions as typed values (``Track`` and
``ObservationMode`` members, a ``Path``) beside the run's config with them written in, read-only. Nothing changes
the caller's config, and nothing later in the run can change the plan's: a write to ``RunPlan.config`` is an error.
"""
from __future__ import annotations

import copy
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf, open_dict

from muble.core.errors import ConfigError
from muble.core.types import ObservationMode, Track
from muble.dataset.protocol import protocol_of, split_spec
from muble.dataset.shipped import check_plays_alone, episodes_root
from muble.episode.components import benchmark_settings
from muble.episode.modes import check_mode, check_track
from muble.episode.sources import dataset_root
from muble.evaluation.files import uses_files

log = logging.getLogger(__name__)

# Where a command reads a protocol split's files from (``resolve``'s ``files``):
# "write": it writes them (``muble generate``): the split at its frozen size, into ``dataset.root``;
# "read": it reads them (``muble eval``): a generated copy in ``dataset.root``, else the shipped files, else
#   ``dataset.root`` as named (the check that follows says how to generate a split that does not ship);
# "serve": it serves them one episode at a time (``muble serve``): as "read", but a split must be there and must
#   play from its files alone (no disturbance acting while it runs).
FILES = ("write", "read", "serve")


@dataclass(frozen=True)
class RunPlan:
    """A command's decisions, made once (``resolve``)."""

    protocol: str | None  # the protocol the run follows (None: none)
    split: str | None  # the protocol's split it runs (None without a protocol)
    splits: tuple[str, ...]  # the dataset splits it reads or writes
    sizes: tuple[int, ...] | None  # their sizes, where the protocol fixes them
    root: Path | None  # where the split's files are (None: outside a Hydra job, no dataset.root exists yet)
    track: Track
    mode: ObservationMode
    config: DictConfig  # the run's config with the above written in; read-only



def resolve(cfg: DictConfig, files: str = "read") -> RunPlan:
    """The plan of a run of ``cfg`` (left as it is) whose command treats a protocol split's files as ``files``
    (``FILES``). A ``ConfigError`` says what to change: an unknown split (the valid ones listed), a track or mode
    MuBlE does not have, a split ``muble serve`` cannot serve."""
    if files not in FILES:
        raise ValueError(f"files must be one of {', '.join(FILES)}, got {files!r}")
    resolved: DictConfig = copy.deepcopy(cfg)
    OmegaConf.set_readonly(resolved, False)
    protocol = protocol_of(resolved)
    split: str | None = None
    sizes: tuple[int, ...] | None = None
    root = _configured_root(resolved)
    if protocol is not None:
        split = str(resolved.benchmark.split)
        spec = split_spec(protocol, split)  # an unknown split: the valid ones listed, the closest suggested
        sizes = (int(spec["size"]),)
        with open_dict(resolved):
            resolved.dataset.splits = [split]
            resolved.dataset.sizes = list(sizes)
        if files != "write" and not uses_files(resolved.dataset):
            root = _episodes_root(resolved, protocol, split, files)
            if root is not None:
                with open_dict(resolved):
                    resolved.dataset.root = str(root)
    try:
        track_name, mode_name = benchmark_settings(resolved)
        track, mode = check_track(track_name), check_mode(mode_name)
    except ValueError as e:
        raise ConfigError(f"{e}; set benchmark.track and benchmark.mode to one of them") from None
    OmegaConf.set_readonly(resolved, True)
    return RunPlan(protocol=None if protocol is None else str(protocol["name"]), split=split,
                   splits=tuple(str(s) for s in resolved.dataset.splits), sizes=sizes, root=root, track=track,
                   mode=mode, config=resolved)


def _configured_root(cfg: DictConfig) -> Path | None:
    return dataset_root(cfg) if "dataset" in cfg else None


def _episodes_root(cfg: DictConfig, protocol: dict[str, Any], split: str, files: str) -> Path | None:
    """Where a command that reads (or serves) ``split`` finds its files."""
    if files == "serve":
        check_plays_alone(cfg, split, "muble serve")
    root = episodes_root(cfg, split)
    if files == "serve" and (root is None or not (root / split).is_dir()):
        raise ConfigError(f"split '{split}' of protocol '{protocol['name']}' does not ship with MuBlE and "
                          "dataset.root holds no copy of it: generate it (`muble generate "
                          f"protocol={protocol['name']} benchmark.split={split} dataset.root=DIR`) and serve it "
                          "with dataset.root=DIR, or serve a split that ships (benchmark.split=mini)")
    configured = _configured_root(cfg)
    if root is not None and root != configured:
        log.info("protocol %s split %s: the shipped files (%s)", protocol["name"], split, root)
    return root
