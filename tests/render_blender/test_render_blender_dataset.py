"""MuJoCo now, Blender later: `muble generate` keeps each episode's keyframe states, and `muble render` draws a
generated episode's keyframes again in Blender from them."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from muble.app.render import main as render
from muble.io.keyframe_states import read_keyframe_states
from muble.io.scene_io import load_scene

pytestmark = [pytest.mark.blender, pytest.mark.slow]

ONE_EPISODE = ["dataset.splits=[val]", "dataset.sizes=[1]", "dataset.sequences=true", "dataset.executor=serial",
               "dataset.templates=[measure_weight_single]", "generator.reach_check=false", "renderer.width=106",
               "renderer.height=60"]


def test_a_generated_episode_is_rendered_again_in_blender(tmp_path):
    root = tmp_path / "ds"
    subprocess.run([sys.executable, "-m", "muble.app.cli", "generate", *ONE_EPISODE, f"dataset.root={root}",
                    f"hydra.run.dir={tmp_path / 'run'}"], check=True, timeout=900, capture_output=True)
    split = root / "val"
    (states_file,) = sorted((split / "keyframes").glob("*_states.npz"))
    stem = states_file.name.removesuffix("_states.npz")
    mujoco_frames = sorted((split / "keyframes" / stem).glob("frame_*.png"))
    states = read_keyframe_states(states_file)
    assert len(mujoco_frames) >= 3 and states.qpos.shape[0] == len(mujoco_frames)
    assert (states.robot, states.object_set, states.camera) == ("Panda", "shopvrb2", "front")
    scene_file = split / "scenes" / f"{stem}.json"

    out = tmp_path / "blender"
    code = render([str(scene_file), "--keyframes", str(states_file), "--renderer", "blender", "--out", str(out),
                   "--passes", "--set", "width=64", "--set", "height=48", "--set", "samples=1",
                   "--set", "denoise=false"])
    assert code == 0
    frames = sorted(out.glob("keyframe_????.png"))
    assert len(frames) == len(mujoco_frames)
    assert np.asarray(Image.open(frames[0])).shape == (48, 64, 3)
    # The keyframes are the episode's states: the arm is drawn where it was (the robot's mask moves), and the
    # scene's objects are on the table.
    first, last = (np.asarray(Image.open(out / f"keyframe_{k:04d}_seg.png")) for k in (0, len(frames) - 1))
    assert ((first == 2) != (last == 2)).sum() > 10
    ids = {o.id for o in load_scene(scene_file).objects}
    assert {3 + i for i in ids} & set(np.unique(first).tolist())
