"""What makes a dataset the dataset it is: the settings that change its files, stored in ``dataset_config.json``
at its root when it is first made. Resuming or extending a dataset (more indices, another split) with other
settings would mix two datasets in one folder, so it is refused, naming each difference.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from muble.core.errors import ConfigError
from muble.io.atomic import write_bytes_atomic

IDENTITY_FILE = "dataset_config.json"

# Top-level keys that do not change a dataset's files (the other jobs' settings, where outputs go).
_NOT_IDENTITY = ("output", "evaluation", "scene_index", "dry_run", "task", "hydra", "benchmark", "train", "trainer")
# dataset.* keys that choose which indices are produced, where and how, not what each one holds.
_NOT_IDENTITY_DATASET = ("root", "executor", "workers", "shard", "num_shards", "ray_address", "splits", "sizes",
                         "start")


def dataset_identity(config: dict[str, Any], current: bool = True) -> dict[str, Any]:
    """The part of a resolved config that decides the content of every index (seeds, templates, generator,
    object set, robot, renderer, planner, agent …), with this MuBlE's ``generator_version`` when ``current``."""
    from muble.generation.generator import GENERATOR_VERSION

    identity = {k: v for k, v in config.items() if k not in _NOT_IDENTITY}
    if current:
        identity["generator_version"] = GENERATOR_VERSION
    identity["dataset"] = {k: v for k, v in config.get("dataset", {}).items() if k not in _NOT_IDENTITY_DATASET}
    if identity.get("protocol"):
        # What a protocol's splits hold, not its bookkeeping: recording a split's hash or size (which index range
        # is produced) changes no index, so a protocol's splits share one dataset folder across those edits.
        protocol = identity["protocol"]
        identity["protocol"] = {
            "name": protocol.get("name"), "version": protocol.get("version"), "common": protocol.get("common"),
            "splits": {name: {k: v for k, v in (spec or {}).items() if k in ("objects", "generator")}
                       for name, spec in (protocol.get("splits") or {}).items()}}
    return identity


ABSENT = object()  # what ``setting_differences`` gives for a key that one side lacks
# Settings that one side may lack, with the value that does what the side without them does: a folder or run that
# lacks the key matches one with that value (``robot.stage`` null: each scene on its own stage, as every run builds
# it; ``generator.stage`` null: robosuite's, see ``_renamed``; ``generator.physical_properties`` empty: none drawn).
ADDED_LATER: dict[str, Any] = {"robot.stage": None, "generator.stage": None, "generator.physical_properties": []}
# Settings a folder may store under a key the config does not have, with the key that decides the same thing:
# the image size and the physics step have one setting each (renderer.width/height, robot.timestep), so a folder
# that stores the generator's own matches a run whose setting has the stored value.
STORED_ELSEWHERE = {"generator.image_width": "renderer.width", "generator.image_height": "renderer.height",
                    "generator.timestep": "robot.timestep"}


def _at(identity: dict[str, Any], key: str) -> Any:
    node: Any = identity
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return ABSENT
        node = node[part]
    return node


def _without_stored_elsewhere(stored: dict[str, Any], requested: dict[str, Any]) -> dict[str, Any]:
    """``stored`` less each ``STORED_ELSEWHERE`` key whose value the requested identity has under its key now."""
    out = json.loads(json.dumps(stored))
    for key, now in STORED_ELSEWHERE.items():
        group, name = key.split(".")
        value = _at(out, key)
        if value is not ABSENT and _at(requested, key) is ABSENT and _at(requested, now) == value:
            del out[group][name]
    return out


def setting_differences(stored: Any, current: Any, where: str = "") -> list[tuple[str, Any, Any]]:
    """(dotted key, stored value, current value) of each setting that differs between two nested dicts, in key
    order; ``ABSENT`` stands for a key that one side lacks."""
    if isinstance(stored, dict) and isinstance(current, dict):
        out: list[tuple[str, Any, Any]] = []
        for key in sorted(set(stored) | set(current), key=str):
            sub = f"{where}.{key}" if where else str(key)
            if key not in stored or key not in current:
                present = stored[key] if key in stored else current[key]
                added = ADDED_LATER.get(sub, ABSENT)
                if added is not ABSENT and _renamed(sub, present) == _renamed(sub, added):
                    continue
                out.append((sub, stored.get(key, ABSENT), current.get(key, ABSENT)))
            else:
                out.extend(setting_differences(stored[key], current[key], sub))
        return out
    return [] if stored == current or _renamed(where, stored) == _renamed(where, current) else [(where, stored, current)]


def _renamed(key: str, value: Any) -> Any:
    """A setting's value under its current name: a folder made before a value was renamed (the step controller's
    old name ``OSC_POSE``, the generator's null stage) still matches a run that uses the new name."""
    if key == "robot.controller" and isinstance(value, str):
        from muble.sim.env import CONTROLLER_ALIASES

        return CONTROLLER_ALIASES.get(value, value)
    if key == "generator.stage" and value is None:
        # A generator without a stage made robosuite's scenes (files naming none), as generator.stage=robosuite
        # (the default, and the protocol's) does: a folder made before still resumes.
        from muble.stage.table import UNNAMED_STAGE

        return UNNAMED_STAGE
    return value


def _difference(key: str, stored: Any, requested: Any) -> str:
    if stored is ABSENT:
        return f"{key}: not stored, requested {json.dumps(requested)}"
    if requested is ABSENT:
        return f"{key}: stored {json.dumps(stored)}, not requested"
    return f"{key}: stored {json.dumps(stored)}, requested {json.dumps(requested)}"


def check_or_store_identity(root: Path, config: dict[str, Any]) -> None:
    """Store the identity of a new dataset at ``root``; for an existing one, raise ``ConfigError`` listing every
    difference between its stored identity and the requested one."""
    requested = json.loads(json.dumps(dataset_identity(config)))  # tuples -> lists, as stored
    path = root / IDENTITY_FILE
    stored = None
    if path.is_file():
        try:
            stored = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise ConfigError(f"{path} cannot be read ({type(e).__name__}: {e}; truncated?): it records the settings "
                              "the dataset in that folder was made with. Restore it, or pass another dataset.root "
                              "for a new dataset") from e
        if not isinstance(stored, dict):
            raise ConfigError(f"{path} holds {type(stored).__name__}, not the settings of a dataset; restore it or "
                              "pass another dataset.root")
    elif (root / "manifest.json").is_file():  # made before identities were stored: its manifest's config
        stored = dataset_identity(json.loads((root / "manifest.json").read_text()).get("config", {}), current=False)
    if stored is None:
        write_bytes_atomic(path, json.dumps(requested, indent=2, sort_keys=True).encode())
        return
    differences = [_difference(*d) for d in setting_differences(_without_stored_elsewhere(stored, requested),
                                                                 requested)]
    if differences:
        shown = "; ".join(differences[:8]) + (f"; and {len(differences) - 8} more" if len(differences) > 8 else "")
        raise ConfigError(f"dataset.root {root} holds a dataset made with other settings ({shown}). To resume or "
                          "extend it, run with its settings (stored in "
                          f"{path.name}); to make a new dataset, pass another dataset.root")
