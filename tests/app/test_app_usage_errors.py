"""Usage errors: every bad command line exits 2 with one paragraph that says what to change, no traceback, and
leaves no folder behind; Hydra's config errors follow the same rule as the project's own."""
from __future__ import annotations

import pytest
from hydra.core.global_hydra import GlobalHydra

from muble.app.config import compose
from muble.app.usage import explain_config_error, suggest
from muble.core.errors import ConfigError
from muble.core.ranges import check_ranges, range_violations
from tests.app.usage_probe import run_many


pytestmark = pytest.mark.usefixtures("clear_hydra")


def _compose_error(overrides: list[str]) -> str:
    with pytest.raises(Exception) as info:
        compose("run", overrides)
    message = explain_config_error(info.value)
    assert message is not None, info.value
    return message


def test_mistyped_key_lists_valid_keys_and_suggests_the_closest():
    message = _compose_error(["renderer.widht=10"])
    assert "'renderer.widht'" in message and "did you mean 'renderer.width'" in message
    assert "valid keys of renderer:" in message and "height" in message


def test_mistyped_top_level_key_lists_top_level_keys():
    message = _compose_error(["sede=3"])
    assert "did you mean 'seed'" in message and "scene_index" in message and "hydra" not in message


def test_wrong_case_option_suggests_the_right_name():
    message = _compose_error(["robot=panda"])
    assert "case-sensitive" in message and "'Panda'" in message
    assert "UR5e" in message and "_schema" not in message


def test_unknown_experiment_is_an_error_not_ignored():
    message = _compose_error(["experiment=nope"])
    assert "quick_mujoco" in message and "photoreal" in message


def test_value_of_the_wrong_type_names_the_key():
    message = _compose_error(["robot.control_freq=fast"])
    assert "robot.control_freq" in message and "fast" in message


def test_suggest_prefers_a_case_insensitive_match():
    assert "case-sensitive" in suggest("ur5E", ["UR5e", "Panda"])
    assert "'Panda'" in suggest("Pandaa", ["UR5e", "Panda"])
    assert suggest("zzz", ["UR5e", "Panda"]) == ""


@pytest.mark.parametrize("override,key", [
    ("robot.control_freq=0", "robot.control_freq"), ("robot.timestep=0", "robot.timestep"),
    ("seed=-1", "seed"), ("scene_index=-1", "scene_index"), ("dataset.start=-5", "dataset.start"),
    ("episode.max_steps=-1", "episode.max_steps"), ("dataset.workers=-3", "dataset.workers"),
    ("dataset.sizes=[3,-1]", "dataset.sizes"), ("dataset.num_shards=0", "dataset.num_shards"),
    ("planner.time_limit=-1", "planner.time_limit"), ("renderer.width=0", "renderer.width"),
])
def test_schema_ranges_reject_nonsense(override, key):
    cfg = compose("run", [override, "dataset.root=/tmp/x", "output.dir=/tmp/x"])
    problems = range_violations(cfg)
    assert len(problems) == 1 and problems[0].startswith(f"{key} must be "), problems
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        check_ranges(cfg)


def test_default_configs_are_in_range():
    for name in ("run", "generate", "eval"):
        GlobalHydra.instance().clear()
        assert range_violations(compose(name, ["dataset.root=/tmp/x", "output.dir=/tmp/x"])) == []


def test_every_usage_error_exits_2_with_one_message_and_leaves_nothing(tmp_path):
    run_dir, sweep_dir = tmp_path / "run", tmp_path / "sweep"
    where = [f"hydra.run.dir={run_dir}", f"hydra.sweep.dir={sweep_dir}"]
    cases = {
        "renderer.widht=10": "renderer.width",
        "robot=panda": "Panda",
        "renderer=nope": "mujoco",
        "seed=[": "cannot parse",
        "robot.control_freq=0": "robot.control_freq",
        "robot.timestep=0": "robot.timestep",
        "seed=-1": "seed",
        "scene_index=-1": "scene_index",
        "episode.max_steps=-1": "episode.max_steps",
        "planner.time_limit=-1": "planner.time_limit",
        "robot.name=???": "robot.name",
    }
    argvs = [[override, *where] for override in cases]
    argvs.append(["-m", "renderer=mujoco,nope", "dry_run=true", *where])
    argvs.append(["generate", "dataset.start=-5", f"dataset.root={tmp_path / 'ds'}", *where])
    argvs.append(["generate", "dataset.workers=-3", f"dataset.root={tmp_path / 'ds'}", *where])
    expected = [*cases.values(), "nope", "dataset.start", "dataset.workers"]
    for result, needle in zip(run_many(argvs, tmp_path), expected):
        assert result["code"] == 2, result
        stderr = result["stderr"].strip()
        assert "Traceback" not in stderr and needle in stderr, result
        assert len(stderr.splitlines()) == 1 and stderr.startswith("muble "), result
    assert not run_dir.exists() and not sweep_dir.exists() and not (tmp_path / "ds").exists()
