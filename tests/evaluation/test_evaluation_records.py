"""The pieces of a resumable evaluation without physics: which indices a split has, the record file read back
after a kill, and the folder's stored settings."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from muble.core.errors import ConfigError, PhysicsError, SceneValidationError
from muble.evaluation.report import bad_entry_table, markdown, summarize
from muble.evaluation.resume import RUN_FILE, EpisodeLog, claim_folder, differences, run_settings
from muble.evaluation.split import check_split, split_indices
from muble.io.layout import DatasetLayout


def _record(index: int, outcome: str = "success", **extra) -> dict:
    return {"index": index, "template": "move_single", "outcome": outcome, "primitives": [], "timing": None,
            "error": None, "file": None, **extra}


def _split(root: Path, instructions: dict[int, dict | None], scenes: list[int], manifest: list[int] | None):
    layout = DatasetLayout(root, "val")
    for index, record in instructions.items():
        path = layout.split_dir / layout.instruction(index)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(record if record is not None else {"instruction": None}))
    for index in scenes:
        path = layout.split_dir / layout.scene(index)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("{}")
    if manifest is not None:
        files = {f"val/{layout.scene(i)}": "0" for i in manifest} | {f"val/{layout.instruction(i)}": "0"
                                                                     for i in manifest}
        (root / "manifest.json").write_text(json.dumps({"files": files}))
    return layout


def test_indices_come_from_the_manifest_not_the_files_present(tmp_path):
    # 0 complete, 1 lost its scene, 2 lost both files, 3 has no template, 4 is newer than the manifest,
    # 5 is a scene an unfinished run left without its instruction (not part of the dataset).
    layout = _split(tmp_path, {0: {"instruction": "x"}, 1: {"instruction": "y"}, 3: None, 4: {"instruction": "z"}},
                    scenes=[0, 3, 4, 5], manifest=[0, 1, 2, 3])
    found = split_indices(layout)
    assert (found.indices, found.skipped, found.source) == ([0, 1, 2, 4], [3], "manifest")
    # An unreadable instruction file is an episode (invalid_data), not a skipped index.
    (layout.split_dir / layout.instruction(3)).write_bytes(b"\xff\xfe{")
    assert split_indices(layout).indices == [0, 1, 2, 3, 4]


def test_without_a_manifest_the_instruction_files_present_are_used(tmp_path):
    layout = _split(tmp_path, {0: {"instruction": "x"}, 2: {"instruction": "y"}}, scenes=[0], manifest=None)
    found = check_split(layout)
    assert found.indices == [0, 2] and "no manifest.json" in found.source
    (tmp_path / "manifest.json").write_text('{"files": ')
    assert "unreadable" in split_indices(layout).source
    with pytest.raises(ConfigError, match="splits present: val"):
        check_split(DatasetLayout(tmp_path, "test"))


def test_a_split_the_manifest_lists_is_evaluated_even_if_its_folder_is_gone(tmp_path):
    layout = _split(tmp_path, {}, scenes=[], manifest=[0, 1])
    assert check_split(layout).indices == [0, 1]


def test_record_file_read_back_after_a_kill(tmp_path):
    log = EpisodeLog(tmp_path / "episodes_val.jsonl")
    assert log.read() == {}
    with log:
        log.append(_record(0))
        log.append(_record(2, "timeout"))
    lines = log.path.read_text()
    # Killed while writing the next line: the partial line is dropped (its index runs again), and so are lines
    # that are JSON but not records.
    log.path.write_text(lines + '{"not": "a record"}\n' + json.dumps(_record(5))[:25])
    done = log.read()
    assert sorted(done) == [0, 2] and done[2]["outcome"] == "timeout"
    log.rewrite(list(done.values()))
    with log:
        log.append(_record(1))
    assert [json.loads(line)["index"] for line in log.path.read_text().splitlines()] == [0, 2, 1]


CONFIG = {"agent": {"name": "oracle"}, "seed": 0, "output": {"dir": "/a"}, "task": {"name": "move_single"},
          "dataset": {"root": "/data", "splits": ["val"], "executor": "serial", "workers": 1},
          "evaluation": {"render": False, "limit": 0, "plot": True}}


def test_folder_refuses_other_settings_and_names_them(tmp_path):
    settings = run_settings(CONFIG, "abc")
    assert "output" not in settings and "executor" not in settings["dataset"] and "limit" not in settings["evaluation"]
    assert claim_folder(tmp_path, settings, ["val"]) is False and (tmp_path / RUN_FILE).is_file()
    # Execution-only settings may change.
    changed = json.loads(json.dumps(CONFIG))
    changed["dataset"].update(executor="processes", workers=8)
    changed["evaluation"].update(limit=5)
    changed["output"]["dir"] = "/b"
    assert claim_folder(tmp_path, run_settings(changed, "abc"), ["val"]) is True
    changed["agent"]["name"], changed["dataset"]["splits"] = "random", ["val", "test"]
    with pytest.raises(ConfigError) as err:
        claim_folder(tmp_path, run_settings(changed, "def"), ["val"])
    message = str(err.value)
    assert "agent.name: 'oracle' -> 'random'" in message and "dataset.splits" in message
    assert "dataset_manifest_sha256: 'abc' -> 'def'" in message and "another folder" in message


def test_renderer_settings_count_only_where_something_is_drawn(tmp_path):
    config = json.loads(json.dumps(CONFIG)) | {"renderer": {"name": "mujoco", "shadow_size": 1024}}
    # A graph-mode run that records no frames builds no renderer: its settings are not the run's.
    assert "renderer" not in run_settings(config, "abc")
    old = run_settings(config, "abc") | {"renderer": {"name": "mujoco"}}  # as runs before this stored them
    (tmp_path / RUN_FILE).write_text(json.dumps({"settings": old}))
    assert claim_folder(tmp_path, run_settings(config, "abc"), ["val"]) is True
    # Drawing frames, or showing the agent images, makes them count.
    for drawn in ({"evaluation": {**config["evaluation"], "render": True}},
                  {"benchmark": {"track": "program", "mode": "masks"}}):
        drawing = config | drawn
        assert run_settings(drawing, "abc")["renderer"] == config["renderer"]
        claim_folder(tmp_path / "new", run_settings(drawing, "abc"), ["val"])
        changed = drawing | {"renderer": {"name": "mujoco", "shadow_size": 4096}}
        with pytest.raises(ConfigError, match="renderer.shadow_size: 1024 -> 4096"):
            claim_folder(tmp_path / "new", run_settings(changed, "abc"), ["val"])
        (tmp_path / "new" / RUN_FILE).unlink()


def test_folder_with_records_but_no_settings_is_refused(tmp_path):
    (tmp_path / "episodes_val.jsonl").write_text(json.dumps(_record(0)) + "\n")
    with pytest.raises(ConfigError, match="without eval_run.json"):
        claim_folder(tmp_path, run_settings(CONFIG, None), ["val"])


def test_differences_lists_added_and_removed_keys():
    assert differences({"a": {"b": 1, "c": 2}}, {"a": {"b": 1, "d": 3}}) == ["a.c: 2 -> (absent)",
                                                                              "a.d: (absent) -> 3"]


def test_bad_entries_counted_in_denominators_and_listed():
    records = [_record(0), _record(1, "invalid_data", file="val/scenes/SHOP_VRB2_val_000001.json", error="truncated"),
               {**_record(2, "invalid_data", file="val/instructions/SHOP_VRB2_val_000002.json", error="UTF-16"),
                "template": "unknown"},
               _record(3, "broken_scene", file="val/scenes/SHOP_VRB2_val_000003.json", error="PhysicsError: x")]
    summary = summarize(records, ["move_single"])
    assert list(summary["templates"]) == ["move_single", "unknown"]
    assert summary["templates"]["move_single"]["success_rate"] == pytest.approx(1 / 3)
    assert summary["overall"]["success_rate"] == pytest.approx(1 / 4)
    assert [e["index"] for e in summary["bad_entries"]] == [1, 2, 3]
    table = bad_entry_table(summary)
    assert "val/instructions/SHOP_VRB2_val_000002.json  invalid_data  UTF-16" in table
    md = markdown({"agent": "oracle", "dataset": "/data", "splits": {"val": summary}}, {})
    assert "| `val/scenes/SHOP_VRB2_val_000003.json` | broken_scene | PhysicsError: x |" in md
    assert bad_entry_table(summarize([_record(0)])) == ""


class _Runner:
    def __init__(self, error: Exception):
        self.error = error

    def execute(self, scene, instruction, task, key=None):
        raise self.error


@pytest.mark.parametrize("error, outcome, says", [
    (ZeroDivisionError("division by zero"), "execution_error", "unexpected ZeroDivisionError: division by zero"),
    (PhysicsError("the simulation state became NaN"), "broken_scene", "PhysicsError: the simulation state"),
    (SceneValidationError("MuJoCo cannot compile the scene"), "invalid_data", "MuJoCo cannot compile"),
])
def test_any_error_in_an_episode_becomes_its_outcome(tmp_path, monkeypatch, error, outcome, says):
    import muble.episode.components
    import muble.evaluation.episodes as episodes
    from tests.core.test_core_data_files import INSTRUCTION, SCENE

    layout = DatasetLayout(tmp_path, "val")
    for rel, data in ((layout.scene(0), SCENE), (layout.instruction(0), INSTRUCTION)):
        (layout.split_dir / rel).parent.mkdir(parents=True, exist_ok=True)
        (layout.split_dir / rel).write_text(json.dumps(data))
    monkeypatch.setattr(episodes, "build_components", lambda config: {})
    monkeypatch.setattr(muble.episode.components, "episode_runner", lambda cfg, components: _Runner(error))
    config = {"dataset": {"root": str(tmp_path)}, "evaluation": {"render": False, "keyframes": False}}
    record = episodes.evaluate_index(episodes.EvalJob(config, "val", 0))
    assert record["outcome"] == outcome and says in record["error"], record
    assert record["template"] == "move_single" and record["primitives"] == [] and record["timing"] is None
    assert record["file"] == (None if outcome == "execution_error" else f"val/{layout.scene(0)}")
