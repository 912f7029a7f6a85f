"""Frozen benchmark protocols: named, versioned splits that any machine regenerates byte for byte.

A protocol is a config of the ``protocol`` group (``muble_conf/protocol/shopvrb2_v1.yaml``). It fixes the
generator, the object set, the template mix and the seed, and names its splits: for each the number of scenes,
the settings it changes (``objects``, ``generator``: what a generalisation split holds out) and the sha256 of its
data, recorded when the protocol was frozen.

Each frozen split also *ships* with MuBlE: its scene and instruction files, compressed, in
``muble_conf/protocol/<name>.<split>.tar.xz`` (``shipped_archive``). ``muble eval protocol=NAME
benchmark.split=SPLIT`` evaluates the shipped files (checked against the recorded hashes, unpacked once into a
cache folder, ``data_cache``) unless ``dataset.root`` holds the split, ``muble data`` writes them to a folder, and
``muble generate protocol=NAME benchmark.split=SPLIT`` regenerates one split and says whether it matches. A report
is labelled with the protocol only when the data's hash is the recorded one. The data hash is the sha256 of the split's *data manifest*: the canonical JSON of
``{relative path: sha256}`` of its scene and instruction files (``data_manifest``), which hold everything that
decides an episode; images, package versions and run times are left out, so the hash says whether two machines
evaluate the same episodes. The manifest itself is recorded beside the protocol's config
(``muble_conf/protocol/<name>.<split>.json``), so a mismatch names the files that differ, and part of a split can
be checked against it.
"""
from __future__ import annotations

import copy
import hashlib
import io
import json
import os
import shutil
import tarfile
import tempfile
from pathlib import Path
from importlib.resources.abc import Traversable
from typing import Any, cast

from muble.core.errors import ConfigError, unknown_name
from muble.io.atomic import check_output_folder, staged_folder
from muble.io.layout import DatasetLayout
from muble.io.manifest import sha256_file

DATA_FOLDERS = ("scenes", "instructions")
ARCHIVE = "{name}.{split}.tar.xz"  # a split's shipped files, beside the protocol's config in muble_conf/protocol
# Where shipped splits are unpacked for `muble eval` (one folder per protocol, split and data hash).
CACHE_ENV = "MUBLE_DATA_CACHE"

# Why a regenerated split can differ from the recorded one on another machine: said where a hash differs.
CPU_NOTE = ("Generation is written to give the same files on every CPU (fixed-order sums instead of BLAS products "
            "where values are written, floats rounded to 9 decimals, named random streams); a differing file means "
            "another MuBlE generator or object set, other physics versions (mujoco, robosuite, numpy, scipy) or a "
            "decision that a last-bit difference between CPUs still flips (docs/protocol.md, \"The same on every "
            "CPU\"). The shipped files are the protocol's: `muble data` writes them and `muble eval` uses them")
SPLIT_GROUPS = ("objects", "generator", "dataset")  # the config groups a protocol's splits may set
# ... and those that act only while its episodes run (muble eval), not on its files: the world pushing back.
EPISODE_GROUPS = ("disturbances", "noise")
PROTOCOL_FILE = "protocol_{split}.json"  # written at the dataset root beside manifest.json


def protocol_of(config: Any) -> dict[str, Any] | None:
    """The protocol section of a config (a DictConfig or a plain dict), None when the run follows none."""
    node = config.get("protocol") if hasattr(config, "get") else None
    if not node:
        return None
    if hasattr(node, "_get_node"):  # a DictConfig: a plain dict from here on
        from omegaconf import OmegaConf

        # a protocol is a mapping (a config of the protocol group): a plain dict of it
        return cast(dict[str, Any], OmegaConf.to_container(node, resolve=True))
    return node


def split_spec(protocol: dict[str, Any], split: str) -> dict[str, Any]:
    """The settings of one split of ``protocol``; an unknown split is a ``ConfigError`` listing the valid ones."""
    splits = protocol.get("splits") or {}
    if split not in splits:
        hint = "; choose it with benchmark.split="
        if split in GENERATED_SPLITS:
            hint += (f" ('{split}' is a split of a dataset `muble generate` wrote: evaluate that with "
                     "dataset.root=DIR and no protocol=)")
        raise ConfigError(unknown_name(f"split of protocol '{protocol.get('name')}'", split, list(splits)) + hint)
    return splits[split]


GENERATED_SPLITS = ("val",)  # the default dataset's split names that no protocol has


def _merge(base: dict[str, Any], extra: dict[str, Any] | None) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for key, value in (extra or {}).items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) \
            else copy.deepcopy(value)
    return out


def split_config(config: dict[str, Any], split: str, groups: tuple[str, ...] = SPLIT_GROUPS) -> dict[str, Any]:
    """``config`` (resolved, plain) as it produces ``split``: the protocol's common ``objects``, ``generator`` and
    ``dataset`` settings, then the split's own (a family's split names its templates under ``dataset``), merged
    over the run's. Unchanged without a protocol or for a split the
    protocol does not name (``muble generate`` refuses those before any work)."""
    protocol = protocol_of(config)
    if protocol is None or split not in (protocol.get("splits") or {}):
        return config
    spec = protocol["splits"][split]
    out = dict(config)
    for group in groups:
        out[group] = _merge(_merge(config.get(group) or {}, (protocol.get("common") or {}).get(group)),
                            spec.get(group))
    return out


def episode_config(config: dict[str, Any], split: str) -> dict[str, Any]:
    """``config`` (resolved, plain) as the episodes of ``split`` run: the protocol split's ``EPISODE_GROUPS``
    (its disturbances, its sensor noise) merged over the run's; unchanged without a protocol or for a split that
    sets none. A frozen split's episodes are the same whatever the command line says of these groups."""
    return split_config(config, split, EPISODE_GROUPS)


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


def check_regenerates(protocol: dict[str, Any]) -> None:
    """Refuse to regenerate a protocol whose files this MuBlE's generator no longer makes (``regenerates: false``):
    its splits are evaluated from the shipped files."""
    if protocol.get("regenerates", True):
        return
    shipped = [s for s in protocol.get("splits", {}) if shipped_archive(protocol, s) is not None]
    raise ConfigError(
        f"protocol {protocol['name']}'s files were made by {protocol.get('generated_by', 'an earlier generator')}, "
        "and this MuBlE's generator makes other scenes, so it is not regenerated. Its shipped splits "
        f"({', '.join(shipped) or 'none'}) are evaluated as they are (`muble eval protocol={protocol['name']} "
        f"benchmark.split=SPLIT`, `muble data protocol={protocol['name']} benchmark.split=SPLIT --out DIR`); "
        "generate new data with protocol=shopvrb2_v2")


def check_data(cfg: Any, root: str | Path, split: str) -> dict[str, Any]:
    """Compare the split's data in ``root`` with the protocol's recorded hash. Returns the stamp a report carries
    (protocol, version, split, data hash); raises ``ConfigError`` when a recorded hash differs, since results on
    other data must not carry the protocol's name."""
    protocol = protocol_of(cfg)
    if protocol is None:
        raise ConfigError(f"the data of split '{split}' in {root} is checked against a protocol's recorded hash, "
                          "and the config follows no protocol (choose one with protocol=NAME)")
    spec = split_spec(protocol, split)
    files = data_manifest(root, split)
    found = manifest_hash(files)
    recorded = spec.get("sha256")
    if recorded and recorded != found:
        raise ConfigError(
            f"the data of split '{split}' in {root} is not protocol {protocol['name']}'s: its data hash is {found}, "
            f"the protocol records {recorded}{_differences(recorded_manifest(protocol, split), files)}. Evaluate "
            f"the shipped files (`muble eval protocol={protocol['name']} benchmark.split={split}` without "
            "dataset.root), regenerate into an empty folder with no other generator, objects, seed or dataset "
            "overrides, or evaluate without protocol= (the report then carries no protocol). " + CPU_NOTE)
    return {"protocol": protocol["name"], "version": protocol.get("version"), "split": split,
            "data_sha256": found, "recorded_sha256": recorded, "matches": recorded == found if recorded else None,
            "files": files}


def protocol_names() -> list[str]:
    """The protocols that ship with MuBlE (``muble_conf/protocol/*.yaml``)."""
    from importlib import resources

    folder = resources.files("muble_conf") / "protocol"
    return sorted(p.name[:-len(".yaml")] for p in folder.iterdir() if p.name.endswith(".yaml"))


def load_protocol(name: str) -> dict[str, Any]:
    """The ``protocol`` section of the protocol config ``name``; an unknown name is a ``ConfigError``."""
    from importlib import resources

    from omegaconf import DictConfig, OmegaConf

    names = protocol_names()
    if name not in names:
        raise ConfigError(unknown_name("protocol", name, names) + "; choose it with protocol=")
    text = (resources.files("muble_conf") / "protocol" / f"{name}.yaml").read_text()
    # a protocol's file is a mapping whose protocol section is one too
    config = cast(DictConfig, OmegaConf.create(text))
    return cast(dict[str, Any], OmegaConf.to_container(config["protocol"], resolve=True))


def shipped_archive(protocol: dict[str, Any], split: str) -> Traversable | None:
    """The shipped archive of ``split`` (an importlib resource), None when the split does not ship (``train``)."""
    from importlib import resources

    path = resources.files("muble_conf") / "protocol" / ARCHIVE.format(name=protocol["name"], split=split)
    return path if path.is_file() else None


def shipped_files(protocol: dict[str, Any], split: str) -> dict[str, bytes]:
    """``{relative path: contents}`` of the split's shipped files, checked file by file against the recorded
    manifest and as a whole against the recorded hash. A split that does not ship, or an archive that does not
    match (a damaged install), is a ``ConfigError``."""
    spec = split_spec(protocol, split)
    archive = shipped_archive(protocol, split)
    if archive is None:
        shipped = [s for s in protocol.get("splits", {}) if shipped_archive(protocol, s) is not None]
        raise ConfigError(f"split '{split}' of protocol '{protocol['name']}' does not ship with MuBlE (splits that "
                          f"do: {', '.join(shipped) or 'none'}); generate it with `muble generate "
                          f"protocol={protocol['name']} benchmark.split={split} dataset.root=DIR`")
    files: dict[str, bytes] = {}
    with tarfile.open(fileobj=io.BytesIO(archive.read_bytes()), mode="r:xz") as tar:
        for member in tar.getmembers():
            if not member.isfile():
                continue
            parts = Path(member.name).parts
            if len(parts) != 3 or parts[0] != split or parts[1] not in DATA_FOLDERS or ".." in parts:
                raise ConfigError(f"{archive}: unexpected member {member.name!r}; reinstall MuBlE")
            data = tar.extractfile(member)
            if data is None:  # a regular file (isfile above) always has contents to read
                raise ConfigError(f"{archive}: member {member.name!r} has no contents; reinstall MuBlE")
            files[member.name] = data.read()
    found = {path: hashlib.sha256(data).hexdigest() for path, data in sorted(files.items())}
    recorded = spec.get("sha256")
    if recorded is None or manifest_hash(found) != recorded:
        raise ConfigError(f"{archive}: the shipped files of split '{split}' do not match protocol "
                          f"{protocol['name']}'s recorded hash{_differences(recorded_manifest(protocol, split), found)}"
                          "; reinstall MuBlE")
    return files


def write_split(protocol: dict[str, Any], split: str, out: str | Path) -> Path:
    """Write the split's shipped scene and instruction files under ``out`` (``out/<split>/scenes``, …), in the
    layout ``muble generate`` writes, atomically: ``out`` gets the whole split or, on any error, nothing.
    Returns ``out``."""
    files = shipped_files(protocol, split)
    out = check_output_folder(out, "--out")
    if (out / split).exists():
        raise ConfigError(f"{out / split} exists; pass an --out without a '{split}' folder (nothing was written)")
    with staged_folder(out, "--out") as stage:
        _write_files(stage, files)
    _add_to_manifest(out, protocol, split, files)
    return out


def _add_to_manifest(root: Path, protocol: dict[str, Any], split: str, files: dict[str, bytes]) -> None:
    """List the split's files in ``root/manifest.json`` (with their sha256, as ``muble generate`` lists what it
    wrote), keeping the entries of other splits already there, so readers find the split's indices in it."""
    from muble.io.atomic import write_bytes_atomic

    path = root / "manifest.json"
    try:
        manifest = json.loads(path.read_text()) if path.is_file() else {}
        listed = dict(manifest.get("files") or {})
    except (OSError, ValueError, AttributeError):
        manifest, listed = {}, {}
    listed.update({rel: hashlib.sha256(data).hexdigest() for rel, data in files.items()})
    manifest.update({"files": dict(sorted(listed.items())), "protocol": protocol["name"],
                     "shipped_splits": sorted({*manifest.get("shipped_splits", []), split})})
    write_bytes_atomic(path, json.dumps(manifest, indent=1, sort_keys=True).encode())


def _write_files(folder: Path, files: dict[str, bytes]) -> None:
    for rel, data in files.items():
        path = folder / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)


def data_cache() -> Path:
    """Where shipped splits are unpacked for evaluation: ``$MUBLE_DATA_CACHE``, else
    ``$XDG_CACHE_HOME/muble/protocols`` (``~/.cache/muble/protocols``)."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "muble" / "protocols"


def shipped_root(protocol: dict[str, Any], split: str) -> Path:
    """A dataset root holding the split's shipped files, unpacked into the cache on first use (atomically, so two
    runs starting together both end with a whole folder) and checked against the recorded hash on every use."""
    recorded = split_spec(protocol, split).get("sha256")
    root = data_cache() / protocol["name"] / f"{split}-{(recorded or 'none')[:16]}"
    if (root / split).is_dir() and data_hash(root, split) == recorded:
        return root
    files = shipped_files(protocol, split)
    root.parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=".unpacking-", dir=root.parent))
    try:
        _write_files(stage, files)
        _add_to_manifest(stage, protocol, split, files)
        if root.exists():  # a damaged earlier copy
            shutil.rmtree(root, ignore_errors=True)
        try:
            os.replace(stage, root)
        except OSError:  # another run published it first
            if not ((root / split).is_dir() and data_hash(root, split) == recorded):
                raise
    finally:
        if stage.exists():
            shutil.rmtree(stage, ignore_errors=True)
    return root


def pack_split(root: str | Path, split: str, archive: str | Path) -> dict[str, str]:
    """Write the split's scene and instruction files under ``root`` into a reproducible xz tar ``archive``
    (members in path order, no times or owners); returns their manifest."""
    files = data_manifest(root, split)
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:xz", format=tarfile.PAX_FORMAT, preset=9) as tar:
        for rel in files:
            data = (Path(root) / rel).read_bytes()
            info = tarfile.TarInfo(rel)
            info.size, info.mtime, info.mode, info.uid, info.gid = len(data), 0, 0o644, 0, 0
            info.uname = info.gname = ""
            tar.addfile(info, io.BytesIO(data))
    tmp = Path(archive).with_name(Path(archive).name + ".tmp")
    tmp.write_bytes(buffer.getvalue())
    os.replace(tmp, archive)
    return files
