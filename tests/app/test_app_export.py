"""`muble export`: generated sequences as a LeRobot dataset that the LeRobot library loads frame for frame."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest


def _muble(*args: str, timeout: int = 600, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "muble.app.cli", *args], capture_output=True, text=True,
                          timeout=timeout, **kwargs)


@pytest.mark.slow
def test_export_loads_in_lerobot_and_every_frame_iterates(tmp_path):
    pytest.importorskip("lerobot", reason='needs the LeRobot library: pip install "muble[lerobot]"')
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root = tmp_path / "ds"
    generated = _muble("generate", "dataset.splits=[val]", "dataset.sizes=[2]",
                       "dataset.templates=[measure_weight_single]", "dataset.executor=serial", "renderer.width=106",
                       "renderer.height=60", f"dataset.root={root}", f"hydra.run.dir={tmp_path / 'run'}", timeout=900)
    assert generated.returncode == 0, generated.stderr[-3000:]
    out = tmp_path / "lerobot"
    result = _muble("export", str(root), "--split", "val", "--out", str(out), "--repo-id", "muble/test")
    assert result.returncode == 0, result.stderr[-3000:]

    sequences = [json.loads(p.read_text()) for p in sorted((root / "val" / "sequences").glob("*.json"))]
    dataset = LeRobotDataset("muble/test", root=out)
    assert dataset.meta.robot_type == "Panda"  # the robot the split was generated with
    assert dataset.num_episodes == len(sequences) == 2
    assert dataset.num_frames == sum(len(s["observations"]) for s in sequences)
    frames = [dataset[i] for i in range(len(dataset))]  # every frame decodes
    for episode, sequence in enumerate(sequences):
        rows = [f for f in frames if int(f["episode_index"]) == episode]
        observations = sequence["observations"]
        assert [int(f["frame_index"]) for f in rows] == list(range(len(observations)))
        assert {f["task"] for f in rows} == {sequence["info"]["instruction"]}
        for f, o in zip(rows, observations):
            robot = o["robot"]
            assert np.allclose(f["observation.state"].numpy(),
                               [*robot["pos"], *robot["ori"], robot["gripper_action"]], atol=1e-5)
            assert float(f["observation.weight"]) == pytest.approx(robot["weight_measurement"], abs=1e-5)
            assert tuple(f["observation.images.front"].shape) == (3, 60, 106)  # channels first, in [0, 1]
            assert 0.0 <= float(f["observation.images.front"].min()) <= float(f["observation.images.front"].max()) <= 1
        # The action of a frame is the primitive that produced the next keyframe, and the state it led to.
        assert [f["action.primitive"] for f in rows] == [o["robot"]["action"][0] for o in observations[1:]] + ["STOP"]
        assert [json.loads(f["action.target"]) for f in rows[:-1]] == [o["robot"]["action"][1] for o in observations[1:]]
        assert np.allclose(rows[0]["action"].numpy(), rows[1]["observation.state"].numpy())


# `import lerobot` fails as it does when the extra is not installed.
WITHOUT_LEROBOT = textwrap.dedent("""
    import importlib.abc, sys

    class NoLerobot(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name == "lerobot" or name.startswith("lerobot."):
                raise ModuleNotFoundError("No module named 'lerobot'", name="lerobot")
            return None

    sys.meta_path.insert(0, NoLerobot())
    from muble.app.cli import main
    sys.exit(main(sys.argv[1:]))
""")


def test_export_without_lerobot_exits_2_naming_the_extra_and_writes_nothing(tmp_path):
    from PIL import Image

    split = tmp_path / "ds" / "val"
    (split / "sequences").mkdir(parents=True)
    (split / "images").mkdir()
    Image.new("RGB", (8, 6)).save(split / "images" / "a.png")
    sequence = {"info": {"instruction": "weigh it"}, "image_paths": ["images/a.png"], "result": "success",
                "observations": [{"robot": {"pos": [0, 0, 0], "ori": [1, 0, 0, 0], "gripper_action": -1,
                                            "weight_measurement": 0.0, "action": ["START", None]}}]}
    (split / "sequences" / "SHOP_VRB2_val_000000.json").write_text(json.dumps(sequence))
    out = tmp_path / "lerobot"
    result = subprocess.run([sys.executable, "-c", WITHOUT_LEROBOT, "export", str(tmp_path / "ds"), "--out",
                             str(out)], capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stdout + result.stderr
    assert 'pip install "muble[lerobot]"' in result.stderr and "Traceback" not in result.stderr
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".muble-tmp-")]


def test_export_without_sequences_says_what_to_do(tmp_path):
    (tmp_path / "val").mkdir()
    result = _muble("export", str(tmp_path), "--out", str(tmp_path / "o"), timeout=300)
    assert result.returncode == 2 and "dataset.sequences=true" in result.stderr
