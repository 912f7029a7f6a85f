"""The yaml files under ``muble_conf`` hold overrides only: a value equal to its schema's default is not written.

A yaml value that restates its schema's default silently overrides that default the day the schema changes it, so
the yaml and the schema disagree without anyone deciding it. Each file is read as written (no composition) and
compared, key by key (nested mappings key by key too), with the defaults of the schema it extends: the
``<name>_schema`` its defaults list names (``muble.app.config.register_configs`` stores one per plugin option from
its registry record's config dataclass, and the ``robot``, ``sensors``, ``disturbances``, ``noise`` and
``generator`` schemas), or the top-level ``muble_schema`` for the primary configs (``run.yaml`` …) and the
``# @package _global_`` experiments. The frozen protocols (``protocol/``) state every setting on purpose and are
not checked.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf

from muble.app.config import EpisodeConfig, RobotConfig, register_configs
from muble.plugins.registry import get_registry

CONF = Path(__file__).resolve().parents[2] / "muble_conf"
# Frozen protocols state every setting that decides their episodes, defaults included (docs/protocol.md).
NOT_CHECKED = ("protocol",)
# Groups whose files are merged into the global package: compared with the top-level schema, as the primary
# configs are.
GLOBAL_GROUPS = ("experiment",)
TOP_SCHEMA = "muble_schema"

# Values kept although they equal their schema's default, because they must not follow it: (file, dotted key) ->
# why. The yaml line says so too, in a comment starting "frozen:". An entry that is no longer a restated default
# fails test_the_frozen_values_are_still_needed.
FROZEN: dict[tuple[str, str], str] = {
    ("experiment/ycb30.yaml", "seed"): "the fixed YCB set is what seed 0 draws (docs/tasks.md)",
    ("experiment/ycb30.yaml", "dataset.template_weights"): "the fixed YCB set deals every template once per block "
                                                           "of ten indices: the uniform mix",
    ("noise/wrist_ft.yaml", "sample_rate_hz"): "the modelled sensor's output rate (Robotiq FT 300-S datasheet); its "
                                               "white noise is given per sample at that rate",
}


def _same(value: Any, default: Any) -> bool:
    # True == 1 in Python; a bool and a number are different settings.
    return isinstance(value, bool) == isinstance(default, bool) and value == default


def _restated(values: dict, defaults: dict, prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted key, value) of every value in ``values`` equal to the one at its key in ``defaults``."""
    found = []
    for key, value in values.items():
        if not isinstance(defaults, dict) or key not in defaults:
            continue
        default, dotted = defaults[key], f"{prefix}{key}"
        if _same(value, default):
            found.append((dotted, value))
        elif isinstance(value, dict) and isinstance(default, dict):
            found += _restated(value, default, f"{dotted}.")
    return found


def _schema_defaults(group: str | None, name: str) -> dict:
    node = ConfigStore.instance().load(f"{group}/{name}.yaml" if group else f"{name}.yaml").node
    return OmegaConf.to_container(node, resolve=False, enum_to_str=True)


def _schema_of(path: Path, conf: Path) -> tuple[str, dict] | None:
    """(name, defaults) of the schema the yaml file extends, or None if its defaults list names none."""
    if path.parent == conf or path.parent.name in GLOBAL_GROUPS:
        return TOP_SCHEMA, _schema_defaults(None, TOP_SCHEMA)
    entries = (yaml.safe_load(path.read_text()) or {}).get("defaults", [])
    names = [e for e in entries if isinstance(e, str) and e.endswith("_schema")]
    return (names[0], _schema_defaults(path.parent.name, names[0])) if names else None


def _values(path: Path) -> dict:
    """The values the file sets itself: no defaults list, no Hydra settings (Hydra's own schema, not MuBlE's)."""
    values = yaml.safe_load(path.read_text()) or {}
    values.pop("defaults", None)
    values.pop("hydra", None)
    return values


def restated_defaults(conf: Path) -> tuple[list[str], list[str]]:
    """(checked files, one line per value a file restates) of the yaml files under ``conf``; a group file that
    names no schema in its defaults list is reported too, as it cannot be checked."""
    register_configs(get_registry())
    checked, problems = [], []
    for path in sorted(conf.rglob("*.yaml")):
        rel = path.relative_to(conf).as_posix()
        if path.parent.name in NOT_CHECKED:
            continue
        schema = _schema_of(path, conf)
        if schema is None:
            problems.append(f"{rel}: names no schema in its defaults list; extend the option's schema "
                            f"(defaults: [{path.stem}_schema, _self_]) so its keys are checked")
            continue
        checked.append(rel)
        for key, value in _restated(_values(path), schema[1]):
            if (rel, key) not in FROZEN:
                problems.append(f"{rel}: {key}: {json.dumps(value)} is the default of {schema[0]}; delete it (the "
                                "schema's default applies), or if the value must stay fixed whatever the default, "
                                "say why in a '# frozen:' comment and add it to FROZEN")
    return checked, problems


def test_no_yaml_restates_a_schema_default():
    checked, problems = restated_defaults(CONF)
    assert not problems, "\n".join(problems)
    groups = {Path(f).parent.name for f in checked if "/" in f}
    expected = {p.name for p in CONF.iterdir() if p.is_dir() and any(p.glob("*.yaml"))} - set(NOT_CHECKED)
    assert groups == expected and "run.yaml" in checked


def test_the_frozen_values_are_still_needed():
    register_configs(get_registry())
    for (rel, key), why in FROZEN.items():
        path = CONF / rel
        assert key in dict(_restated(_values(path), _schema_of(path, CONF)[1])), \
            f"{rel}: {key} no longer restates its schema's default; drop it from FROZEN ({why})"
        leaf = key.rpartition(".")[2]
        line = next(ln for ln in path.read_text().splitlines() if ln.strip().startswith(f"{leaf}:"))
        assert "# frozen:" in line, f"{rel}: the line of {key} must say why it is frozen ('# frozen: {why}')"


def test_a_restated_default_is_named_by_file_and_key(tmp_path):
    (tmp_path / "task").mkdir()
    (tmp_path / "task" / "remove.yaml").write_text(
        "defaults:\n  - remove_schema\n  - _self_\n\nextra_steps: 0\ninstructions_per_scene: 3\n")
    (tmp_path / "experiment").mkdir()
    (tmp_path / "experiment" / "x.yaml").write_text(
        "# @package _global_\ndataset:\n  workers: 2\n  sizes: [5]\nepisode:\n  max_steps: 7\n")
    (tmp_path / "agent").mkdir()
    (tmp_path / "agent" / "bare.yaml").write_text("seed: 3\n")
    (tmp_path / "run.yaml").write_text("defaults:\n  - muble_schema\n  - _self_\n\nseed: 0\n"
                                       "scene_index: 4\nhydra:\n  job:\n    chdir: false\n")
    checked, problems = restated_defaults(tmp_path)
    assert sorted(checked) == ["experiment/x.yaml", "run.yaml", "task/remove.yaml"]
    assert len(problems) == 4, problems
    text = "\n".join(problems)
    assert "task/remove.yaml: extra_steps: 0 is the default of remove_schema; delete it" in text
    assert "experiment/x.yaml: dataset.workers: 2 is the default of muble_schema" in text
    assert "run.yaml: seed: 0 is the default of muble_schema" in text
    assert "agent/bare.yaml: names no schema" in text
    assert "instructions_per_scene" not in text and "sizes" not in text and "max_steps" not in text


@pytest.mark.parametrize("value,default,same", [(True, 1, False), (0, False, False), (2, 2.0, True),
                                                ([1, 2], [1, 2], True), ({}, {}, True), ("a", "b", False)])
def test_values_are_compared_as_settings(value, default, same):
    assert _same(value, default) is same


def test_the_robot_defaults_of_the_environment_are_the_schemas():
    """The robot defaults are written once (``muble.core.environment.ROBOT_DEFAULTS``): the ``robot`` schema takes
    its defaults from them, an environment built with no robot config (the Gymnasium environments, the generator's
    checks, tests) uses them, and the run config's robot group names their robot. A literal written into the
    schema instead, or another robot chosen by run.yaml, fails here."""
    import dataclasses

    from muble.sim.env import ROBOT_DEFAULTS

    schema = {f.name: f.default for f in dataclasses.fields(RobotConfig) if f.name != "name"}
    assert {k: ROBOT_DEFAULTS[k] for k in schema} == schema
    run_defaults = yaml.safe_load((CONF / "run.yaml").read_text())["defaults"]
    assert ROBOT_DEFAULTS["name"] == next(e["robot"] for e in run_defaults if isinstance(e, dict) and "robot" in e)


def test_the_episode_limit_has_one_value():
    from muble.episode import DEFAULT_MAX_STEPS, EpisodeMonitor

    assert EpisodeConfig().max_steps == EpisodeMonitor().max_steps == DEFAULT_MAX_STEPS
