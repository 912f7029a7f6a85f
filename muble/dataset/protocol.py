"""Frozen benchmark protocols: named, versioned splits that any machine regenerates byte for byte.

A protocol is a config of the ``protocol`` group (``muble_conf/protocol/shopvrb2_v1.yaml``). It fixes the
generator, the object set, the template mix and the seed, and names its splits: for each the number of scenes,
the settings it changes (``objects``, ``generator``: what a generalisation split holds out) and the sha256 of its
data, recorded when the protocol was frozen.

``muble generate protocol=NAME benchmark.split=SPLIT`` writes one split; ``muble eval protocol=NAME
benchmark.split=SPLIT`` evaluates it and labels the report with the protocol only when the data's hash is the
recorded one. The data hash is the sha256 of the split's *data manifest*: the canonical JSON of
``{relative path: sha256}`` of its scene and instruction files (``data_manifest``), which hold everything that
decides an episode; images, package versions and run times are left out, so the hash says whether two machines
evaluate the same episodes. The manifest itself is recorded beside the protocol's config
(``muble_conf/protocol/<name>.<split>.json``), so a mismatch names the files that differ, and part of a split can
be checked against it.
"""
from __future__ import annotations

import copy
import hashlib
import json
from pathlib import Path
from typing import Any

from muble.core.errors import ConfigError, unknown_name
from muble.core.layout import DatasetLayout
from muble.core.manifest import sha256_file

DATA_FOLDERS = ("scenes", "instructions")
PROTOCOL_FILE = "protocol_{split}.json"  # written at the dataset root beside manifest.json


def protocol_of(config: Any) -> dict[str, Any] | None:
    """The protocol section of a config (a DictConfig or a plain dict), None when the run follows none."""
    node = config.get("protocol") if hasattr(config, "get") else None
    if not node:
        return None
    if hasattr(node, "_get_node"):  # a DictConfig: a plain dict from here on
        from omegaconf import OmegaConf

        node = OmegaConf.to_container(node, resolve=True)
    return node


def split_spec(protocol: dict[str, Any], split: str) -> dict[str, Any]:
    """The settings of one split of ``protocol``; an unknown split is a ``ConfigError`` listing the valid ones."""
    splits = protocol.get("splits") or {}
    if split not in splits:
        raise ConfigError(unknown_name(f"split of protocol '{protocol.get('name')}'", split, list(splits))
                          + "; choose it with benchmark.split=")
    return splits[split]


def _merge(base: dict[str, Any], extra: dict[str, Any] | None) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for key, value in (extra or {}).items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) \
            else copy.deepcopy(value)
    return out


def split_config(config: dict[str, Any], split: str) -> dict[str, Any]:
    """``config`` (resolved, plain) as it produces ``split``: the protocol's common ``objects`` and ``generator``
    settings, then the split's own, merged over the run's. Unchanged without a protocol or for a split the
    protocol does not name (``muble generate`` refuses those before any work)."""
    protocol = protocol_of(config)
    if protocol is None or split not in (protocol.get("splits") or {}):
        return config
    spec = protocol["splits"][split]
    out = dict(config)
    for group in ("objects", "generator"):
        out[group] = _merge(_merge(config[group], (protocol.get("common") or {}).get(group)), spec.get(group))
    return out


def select_split(cfg: Any) -> str | None:
    """With a protocol: point ``dataset.splits`` and ``dataset.sizes`` at the split ``benchmark.split`` names
    (in place) and return its name; None without a protocol."""
    from omegaconf import open_dict

    protocol = protocol_of(cfg)
    if protocol is None:
        return None
    split = str(cfg.benchmark.split)
    spec = split_spec(protocol, split)
    with open_dict(cfg):
        cfg.dataset.splits = [split]
        cfg.dataset.sizes = [int(spec["size"])]
    return split


def data_manifest(root: str | Path, split: str) -> dict[str, str]:
    """``{relative path: sha256}`` of the split's scene and instruction files, in path order."""
    layout = DatasetLayout(Path(root), split)
    files = {}
    for folder in DATA_FOLDERS:
        directory = layout.split_dir / folder
        if directory.is_dir():
            for path in sorted(directory.glob("*.json")):
                files[str(path.relative_to(layout.root))] = sha256_file(path)
    return files


def data_hash(root: str | Path, split: str) -> str:
    """The sha256 of the split's data manifest as canonical JSON (sorted keys, no spaces)."""
    return manifest_hash(data_manifest(root, split))


def manifest_hash(files: dict[str, str]) -> str:
    return hashlib.sha256(json.dumps(files, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def recorded_manifest(protocol: dict[str, Any], split: str) -> dict[str, str] | None:
    """The data manifest recorded beside the protocol's config when the split was frozen
    (``muble_conf/protocol/<name>.<split>.json``), None if none was."""
    from importlib import resources

    try:
        text = (resources.files("muble_conf") / "protocol" / f"{protocol['name']}.{split}.json").read_text()
    except (FileNotFoundError, OSError):
        return None
    return json.loads(text)["files"]


def _differences(recorded: dict[str, str] | None, found: dict[str, str], limit: int = 5) -> str:
    """Which of ``found``'s files differ from the recorded manifest, and how many recorded files are missing."""
    if recorded is None:
        return ""
    changed = sorted(k for k in found if recorded.get(k) != found[k])
    missing = len(set(recorded) - set(found))
    parts = []
    if changed:
        shown = ", ".join(changed[:limit]) + (f" and {len(changed) - limit} more" if len(changed) > limit else "")
        parts.append(f"{len(changed)} of its files differ from the recorded ones: {shown}")
    if missing:
        parts.append(f"{missing} recorded files are missing")
    return f" ({'; '.join(parts)})" if parts else ""


def check_data(cfg: Any, root: str | Path, split: str) -> dict[str, Any]:
    """Compare the split's data in ``root`` with the protocol's recorded hash. Returns the stamp a report carries
    (protocol, version, split, data hash); raises ``ConfigError`` when a recorded hash differs, since results on
    other data must not carry the protocol's name."""
    protocol = protocol_of(cfg)
    spec = split_spec(protocol, split)
    files = data_manifest(root, split)
    found = manifest_hash(files)
    recorded = spec.get("sha256")
    if recorded and recorded != found:
        raise ConfigError(
            f"the data of split '{split}' in {root} is not protocol {protocol['name']}'s: its data hash is {found}, "
            f"the protocol records {recorded}{_differences(recorded_manifest(protocol, split), files)}. Regenerate it into an empty folder with `muble generate "
            f"protocol={protocol['name']} benchmark.split={split} dataset.root=DIR` and no other generator, objects, "
            "seed or dataset overrides, or evaluate without protocol= (the report then carries no protocol)")
    return {"protocol": protocol["name"], "version": protocol.get("version"), "split": split,
            "data_sha256": found, "recorded_sha256": recorded, "matches": recorded == found if recorded else None,
            "files": files}
