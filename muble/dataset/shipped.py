"""Where a config's stored episodes of a split are: a dataset folder, or a frozen protocol's shipped files.

``muble eval``, the Gymnasium environments and ``muble serve`` all ask here, so ``protocol=shopvrb2_v2`` plays the
shipped episodes everywhere with no generation or ``muble data`` step: a split of the protocol that ships is
unpacked into the cache once and hash-checked on every use (``muble.dataset.protocol.shipped_root``). A folder
``dataset.root`` names that already holds the split wins (a split generated with ``muble generate protocol=…``).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from muble.core.errors import ConfigError
from muble.dataset.protocol import EPISODE_GROUPS, protocol_names, protocol_of, shipped_archive, shipped_root
from muble.episode.sources import dataset_root


def shipped_split_root(cfg: Any, split: str) -> Path | None:
    """With a protocol (``protocol=NAME``) of which ``split`` ships: the root of its shipped files; else None."""
    protocol = protocol_of(cfg)
    if protocol is None or split not in (protocol.get("splits") or {}) or shipped_archive(protocol, split) is None:
        return None
    return shipped_root(protocol, split)


def check_plays_alone(cfg: Any, split: str, where: str) -> None:
    """Refuse (``ConfigError``) a protocol split whose episodes need more than their files: one that sets what acts
    while they run (``EPISODE_GROUPS``: the closed_loop split's disturbances, drawn per episode), which only
    ``muble eval`` applies; ``where`` names the caller (``muble serve``, ``the Gymnasium environment``)."""
    protocol = protocol_of(cfg)
    if protocol is None or not isinstance(split, str):
        return  # no protocol split: nothing acts but what the caller applies
    spec = protocol.get("splits", {}).get(split)
    acting = [group for group in EPISODE_GROUPS if (spec or {}).get(group)]
    if acting:
        raise ConfigError(f"split '{split}' of protocol '{protocol['name']}' sets {' and '.join(acting)} that act "
                          f"while its episodes run, which {where} does not apply (its episodes would not be the "
                          f"benchmark's): evaluate it with `muble eval protocol={protocol['name']} "
                          f"benchmark.split={split}`, or choose another split")


def episodes_root(cfg: Any, split: str) -> Path | None:
    """The dataset root holding ``split``'s stored episodes for ``cfg``: ``dataset.root`` when it holds the split,
    else the protocol's shipped files of the split, else ``dataset.root`` as named (None where none is: outside a
    Hydra job the default ``dataset.root``, a run folder, does not exist)."""
    root = dataset_root(cfg)
    if root is not None and (root / split).is_dir():
        return root
    shipped = shipped_split_root(cfg, split)
    return shipped if shipped is not None else root


def newest_protocol() -> str | None:
    """The protocol an error suggests where none was chosen: the last shipped one by name (names end in their
    version: shopvrb2_v1, shopvrb2_v2); None if none ships."""
    names = protocol_names()
    return names[-1] if names else None
