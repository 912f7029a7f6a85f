"""Bad files and paths given to `muble render`, `muble export` and `muble generate`: each is one message on
stderr, exit code 2, no traceback, and nothing written (no output folder, no partial files)."""
from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import numpy as np
import pytest

from muble.core.errors import ConfigError
from muble.io.atomic import staged_folder, write_bytes_atomic
from muble.io.keyframe_states import KeyframeStates, keyframe_states_bytes, read_keyframe_states
from muble.io.layout import DatasetLayout, check_split_name
from tests.app.usage_probe import run_many

SCENE = Path(__file__).resolve().parents[1] / "planning" / "data" / "glass_beside_a_tall_thermos.json"


def _assert_usage_errors(results: list[dict], needles: list[str]) -> None:
    assert len(results) == len(needles)
    for result, needle in zip(results, needles):
        stderr = result["stderr"].strip()
        assert result["code"] == 2, result
        assert "Traceback" not in stderr and needle in stderr, (needle, result)
        assert len(stderr.splitlines()) == 1, result


@pytest.fixture
def bad_files(tmp_path: Path) -> dict[str, Path]:
    files = {
        "binary": b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe garbage",
        "utf16": '{"objects": []}'.encode("utf-16"),
        "nested": b"[" * 100_000 + b"]" * 100_000,
        "huge_int": b'{"objects": [], "n": ' + b"9" * 5000 + b"}",
        "huge_float": json.dumps({"split": "val", "image_index": 0, "image_filename": "x.png",
                                  "objects": []}).replace('"image_index": 0', '"image_index": 1e400').encode(),
        "truncated": SCENE.read_bytes()[:200],
    }
    out = {}
    for name, data in files.items():
        out[name] = tmp_path / f"{name}.json"
        out[name].write_bytes(data)
    (tmp_path / "a_file").write_text("x")
    out["a_file"] = tmp_path / "a_file"
    np.save(tmp_path / "single.npy", np.zeros((2, 3)))
    out["npy"] = tmp_path / "single.npy"
    np.savez(tmp_path / "no_qpos.npz", states=np.zeros((2, 3)))
    out["no_qpos"] = tmp_path / "no_qpos.npz"
    np.savez(tmp_path / "flat.npz", qpos=np.zeros(7))
    out["flat"] = tmp_path / "flat.npz"
    np.savez(tmp_path / "nan.npz", qpos=np.full((2, 3), np.nan))
    out["nan"] = tmp_path / "nan.npz"
    np.savez(tmp_path / "wrong_nq.npz", qpos=np.zeros((2, 3)))
    out["wrong_nq"] = tmp_path / "wrong_nq.npz"
    return out


def test_render_bad_inputs_exit_2_and_write_nothing(tmp_path, bad_files):
    out = tmp_path / "renders"
    scene = str(SCENE)
    cases = [
        (["render", str(tmp_path / "missing.json"), "--out", str(out)], "does not exist"),
        (["render", str(tmp_path), "--out", str(out)], str(tmp_path)),
        (["render", str(bad_files["binary"]), "--out", str(out)], "not UTF-8"),
        (["render", str(bad_files["utf16"]), "--out", str(out)], "UTF-16"),
        (["render", str(bad_files["nested"]), "--out", str(out)], "nested.json"),
        (["render", str(bad_files["huge_int"]), "--out", str(out)], "huge_int.json"),
        (["render", str(bad_files["huge_float"]), "--out", str(out)], "huge_float.json"),
        (["render", str(bad_files["truncated"]), "--out", str(out)], "truncated"),
        (["render", scene, "--out", str(bad_files["a_file"])], "is a file"),
        (["render", scene, "--out", str(bad_files["a_file"] / "sub")], "is a file"),
        (["render", scene, "--out", str(out), "--keyframes", str(tmp_path / "none.npz")], "does not exist"),
        (["render", scene, "--out", str(out), "--keyframes", str(bad_files["a_file"])], "not a readable .npz"),
        (["render", scene, "--out", str(out), "--keyframes", str(bad_files["npy"])], "single .npy"),
        (["render", scene, "--out", str(out), "--keyframes", str(bad_files["no_qpos"])], "no 'qpos'"),
        (["render", scene, "--out", str(out), "--keyframes", str(bad_files["flat"])], "(keyframes, nq)"),
        (["render", scene, "--out", str(out), "--keyframes", str(bad_files["nan"])], "NaN"),
        (["render", scene, "--out", str(out), "--renderer", "mujocoo"], "did you mean 'mujoco'"),
        (["render", scene, "--out", str(out), "--object-set", "YCB"], "'ycb'"),
        (["render", scene, "--out", str(out), "--renderer", "mujoco", "--set", "width=0"], "width must be >= 1, got 0"),
        (["render", scene, "--out", str(out), "--renderer", "mujoco", "--set", "widht=10"], "widht"),
        (["render", scene, "--out", str(out), "--renderer", "mujoco", "--set", "width"], "KEY=VALUE"),
        (["render", scene, "--out", str(out), "--renderer", "mujoco", "--camera", "Front"], "'front'"),
        (["render", scene, "--out", str(out), "--renderer", "mujoco", "--keyframes", str(bad_files["wrong_nq"])],
         "nq="),
    ]
    results = run_many([argv for argv, _ in cases], tmp_path)
    _assert_usage_errors(results, [needle for _, needle in cases])
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".muble-tmp-")]


def _fake_split(root: Path, sequence_text: str) -> None:
    (root / "val" / "sequences").mkdir(parents=True)
    (root / "val" / "sequences" / "SHOP_VRB2_val_000000.json").write_text(sequence_text)


def test_export_bad_inputs_exit_2_and_write_nothing(tmp_path):
    good = {"info": {"instruction": "weigh it"}, "image_paths": ["images/a.png"], "result": "success",
            "observations": [{"robot": {"pos": [0, 0, 0], "ori": [1, 0, 0, 0], "gripper_action": -1,
                                        "weight_measurement": 0.0, "action": ["START", None]}}]}
    roots = {name: tmp_path / name for name in ("truncated", "no_field", "no_image")}
    _fake_split(roots["truncated"], json.dumps(good)[:60])
    _fake_split(roots["no_field"], json.dumps({k: v for k, v in good.items() if k != "image_paths"}))
    _fake_split(roots["no_image"], json.dumps(good))
    # A second, complete sequence before the bad one: a failed export must not leave its files either.
    out = tmp_path / "lerobot"
    (tmp_path / "a_file").write_text("x")
    cases = [
        (["export", str(roots["truncated"]), "--out", str(out)], "truncated"),
        (["export", str(roots["no_field"]), "--out", str(out)], "'image_paths'"),
        (["export", str(roots["no_image"]), "--out", str(out)], "missing"),
        (["export", str(tmp_path / "nowhere"), "--out", str(out)], "does not exist"),
        (["export", str(roots["no_image"]), "--split", "../x", "--out", str(out)], "invalid split name"),
        (["export", str(roots["no_image"]), "--out", str(tmp_path / "a_file")], "is a file"),
        (["export", str(roots["no_image"]), "--out", str(roots["truncated"])], "not a LeRobot export"),
    ]
    results = run_many([argv for argv, _ in cases], tmp_path)
    _assert_usage_errors(results, [needle for _, needle in cases])
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".muble-tmp-")]


def test_generate_refuses_a_split_outside_the_root(tmp_path):
    root = tmp_path / "ds"
    results = run_many([["generate", "dataset.splits=[../../escape]", "dataset.sizes=[1]", f"dataset.root={root}",
                         f"hydra.run.dir={tmp_path / 'run'}"],
                        ["generate", "dataset.splits=[val]", "dataset.sizes=[1]", f"dataset.root={tmp_path / 'f'}",
                         f"hydra.run.dir={tmp_path / 'run'}", "dataset.executor=serial"]],
                       tmp_path) if (tmp_path / "f").write_text("x") else []
    _assert_usage_errors(results, ["invalid split name", "is a file"])
    assert not root.exists() and not (tmp_path / "escape").exists() and not (tmp_path / "run").exists()


@pytest.mark.parametrize("name", ["../escape", "a/b", "..", ".hidden", "", "a\\b", "x" * 100])
def test_split_names_with_path_parts_are_refused(name):
    with pytest.raises(ConfigError, match="invalid split name"):
        check_split_name(name)
    with pytest.raises(ConfigError):
        DatasetLayout(Path("/tmp"), name)


def test_atomic_files_and_staged_folders_follow_the_umask(tmp_path):
    old = os.umask(0o027)
    try:
        write_bytes_atomic(tmp_path / "a" / "f.json", b"{}")
        with staged_folder(tmp_path / "out") as stage:
            (stage / "sub").mkdir()
            write_bytes_atomic(stage / "sub" / "g.json", b"{}")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a" / "f.json").stat().st_mode) == 0o640
    assert stat.S_IMODE((tmp_path / "out").stat().st_mode) == 0o750
    assert stat.S_IMODE((tmp_path / "out" / "sub" / "g.json").stat().st_mode) == 0o640
    os.umask(0o022)
    try:
        write_bytes_atomic(tmp_path / "b.json", b"{}")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "b.json").stat().st_mode) == 0o644


def test_staged_folder_leaves_nothing_when_the_block_fails(tmp_path):
    with pytest.raises(RuntimeError):
        with staged_folder(tmp_path / "x" / "out") as stage:
            (stage / "partial.png").write_bytes(b"1")
            raise RuntimeError("render failed")
    assert list(tmp_path.iterdir()) == []


def test_keyframe_state_files_round_trip(tmp_path):
    states = KeyframeStates(np.arange(12.0).reshape(3, 4), robot="UR5e", object_set="ycb", camera="front")
    path = tmp_path / "s.npz"
    path.write_bytes(keyframe_states_bytes(states))
    back = read_keyframe_states(path)
    assert np.array_equal(back.qpos, states.qpos)
    assert (back.robot, back.object_set, back.camera) == ("UR5e", "ycb", "front")
