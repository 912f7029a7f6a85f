"""Export generated SHOP-VRB2 sequences as a LeRobot dataset, written by LeRobot's own writer.

Each episode is one sequence file; each frame is the keyframe after a primitive (frame 0: the start). Per frame:
``observation.images.front`` (the keyframe image), ``observation.state`` (end-effector position, quaternion
w x y z, gripper command: 8 floats), ``observation.weight`` (the measured weight in grams), ``action`` (the state the
primitive led to: the next frame's state, the last frame repeats its own), ``action.primitive`` and
``action.target`` (the primitive that produced the *next* frame, ``STOP`` after the last, and its target as JSON),
and the instruction as the frame's task. ``robot_type`` is the robot's name.

``LeRobotDataset.create`` / ``add_frame`` / ``save_episode`` / ``finalize`` write the current format of the
installed ``lerobot`` (dataset format v3.0 for lerobot 0.4 and 0.6): ``meta/info.json``, ``meta/stats.json``,
``meta/tasks.parquet``, ``meta/episodes/…``, ``data/chunk-000/file-000.parquet`` with the images embedded.
``lerobot`` is the extra ``muble[lerobot]``. Frames are keyframes, not a fixed control rate: ``fps`` is 1 and a
frame's ``timestamp`` is its index.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from muble.core.errors import ConfigError, SceneValidationError
from muble.io.layout import DatasetLayout

IMAGE_KEY = "observation.images.front"
STATE_NAMES = ["x", "y", "z", "qw", "qx", "qy", "qz", "gripper"]
FPS = 1
INSTALL = 'pip install "muble[lerobot]"'


def _state(robot: dict[str, Any]) -> list[float]:
    return [*map(float, robot["pos"]), *map(float, robot["ori"]), float(robot["gripper_action"])]


def lerobot_version() -> str | None:
    """The installed lerobot's version, or ``None`` when it is not installed."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("lerobot")
    except PackageNotFoundError:
        return None


def require_lerobot() -> None:
    """A ``ConfigError`` naming the extra when the LeRobot library cannot be imported."""
    import importlib.util

    try:
        found = importlib.util.find_spec("lerobot") is not None
    except (ImportError, ValueError):
        found = False
    if not found:
        raise ConfigError(f"`muble export` writes with the LeRobot library, which is not installed: {INSTALL} "
                          "(lerobot 0.6 on Python 3.13; it brings torch)")


def read_sequence(path: Path, split_dir: Path) -> dict[str, Any]:
    """A sequence file, checked for what the export reads: a ``SceneValidationError`` names the file and the
    missing or malformed field (a truncated or hand-edited file), a ``ConfigError`` a missing keyframe image."""
    from muble.io.scene_io import read_json

    sequence = read_json(path)
    try:
        observations = sequence["observations"]
        task = sequence["info"]["instruction"]
        images = sequence["image_paths"]
        if not isinstance(observations, list) or not observations:
            raise TypeError("'observations' must be a non-empty list")
        if not isinstance(images, list) or len(images) != len(observations):
            raise TypeError(f"'image_paths' must list one image per observation ({len(observations)})")
        for o in observations:
            robot = o["robot"]
            _state(robot), float(robot["weight_measurement"]), robot["action"][0]
    except (KeyError, IndexError, TypeError, ValueError) as e:
        what = f"missing field {e}" if isinstance(e, KeyError) else str(e)
        raise SceneValidationError(f"{path}: not a complete sequence file ({what}); generate the split again "
                                   "or remove the file") from e
    if not isinstance(task, str) or not task:
        raise SceneValidationError(f"{path}: 'info.instruction' must be text", field="instruction")
    missing = [p for p in images if not (split_dir / p).is_file()]
    if missing:
        raise ConfigError(f"{path}: {len(missing)} keyframe image(s) missing, first {split_dir / missing[0]}; "
                          "generate the split again")
    return sequence


def dataset_robot(root: Path) -> str | None:
    """The robot a generated dataset was made with (its ``dataset_config.json`` or ``manifest.json``)."""
    from muble.dataset.identity import IDENTITY_FILE

    for name in (IDENTITY_FILE, "manifest.json"):
        path = root / name
        if not path.is_file():
            continue
        try:
            record = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        config = record.get("config", record) if isinstance(record, dict) else {}
        robot = config.get("robot") if isinstance(config, dict) else None
        name_ = robot.get("name") if isinstance(robot, dict) else robot
        if isinstance(name_, str) and name_:
            return name_
    return None


def _image(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"))


def _image_shape(path: Path) -> tuple[int, int, int]:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as image:
            return image.height, image.width, 3
    except (OSError, UnidentifiedImageError) as e:
        raise ConfigError(f"{path}: not a readable keyframe image ({e}); generate the split again") from e


def features(image_shape: tuple[int, int, int]) -> dict[str, dict[str, Any]]:
    """The dataset's features in LeRobot's terms (LeRobot adds timestamp, frame, episode, index and task index)."""
    return {
        IMAGE_KEY: {"dtype": "image", "shape": image_shape, "names": ["height", "width", "channels"]},
        "observation.state": {"dtype": "float32", "shape": (len(STATE_NAMES),), "names": STATE_NAMES},
        "observation.weight": {"dtype": "float32", "shape": (1,), "names": ["grams"]},
        "action": {"dtype": "float32", "shape": (len(STATE_NAMES),), "names": STATE_NAMES},
        "action.primitive": {"dtype": "string", "shape": (1,), "names": None},
        "action.target": {"dtype": "string", "shape": (1,), "names": None},
    }


@dataclass(frozen=True)
class CheckedSplit:
    """A split whose every sequence file and keyframe image was checked: ready to write."""

    layout: DatasetLayout
    sequences: list[dict[str, Any]]
    image_shape: tuple[int, int, int]


def check_split(dataset_root: str | Path, split: str) -> CheckedSplit:
    """Read and check every sequence of the split (needs no LeRobot): a ``MubleError`` names the first problem."""
    layout = DatasetLayout(Path(dataset_root), split)
    paths = sorted((layout.split_dir / "sequences").glob("*.json"))
    if not paths:
        raise ConfigError(f"no sequence files under {layout.split_dir / 'sequences'}; generate the split with "
                          "dataset.sequences=true first")
    sequences = [read_sequence(path, layout.split_dir) for path in paths]
    shapes = {_image_shape(layout.split_dir / p) for s in sequences for p in s["image_paths"]}
    if len(shapes) > 1:
        raise ConfigError(f"keyframe images of split '{split}' differ in size ({sorted(shapes)}); a LeRobot "
                          "dataset has one image shape: generate the split with one renderer size")
    return CheckedSplit(layout, sequences, shapes.pop())


def write_lerobot(checked: CheckedSplit, out: str | Path, robot_type: str | None = None,
                  repo_id: str = "muble/shopvrb2") -> dict[str, Any]:
    """Write a checked split as a LeRobot dataset in ``out`` (a folder that must not exist yet: LeRobot creates
    it). ``robot_type`` defaults to the robot the dataset was generated with. Returns the episode and frame counts,
    the robot type and the lerobot version."""
    require_lerobot()
    robot_type = robot_type or dataset_robot(checked.layout.root)
    if not robot_type:
        raise ConfigError(f"{checked.layout.root} records no robot (no dataset_config.json or manifest.json): pass "
                          "--robot-type NAME")
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    split_dir = checked.layout.split_dir
    dataset = LeRobotDataset.create(repo_id, FPS, features(checked.image_shape), root=Path(out),
                                    robot_type=robot_type, use_videos=False)
    total = 0
    try:
        for sequence in checked.sequences:
            observations = sequence["observations"]
            states = np.asarray([_state(o["robot"]) for o in observations], dtype=np.float32)
            for i, obs in enumerate(observations):
                following = observations[i + 1]["robot"]["action"] if i + 1 < len(observations) else ["STOP", None]
                dataset.add_frame({
                    IMAGE_KEY: _image(split_dir / sequence["image_paths"][i]),
                    "observation.state": states[i],
                    "observation.weight": np.asarray([obs["robot"]["weight_measurement"]], dtype=np.float32),
                    "action": states[min(i + 1, len(states) - 1)],
                    "action.primitive": str(following[0]),
                    "action.target": json.dumps(following[1] if len(following) > 1 else None),
                    "task": sequence["info"]["instruction"],
                })
            dataset.save_episode()
            total += len(observations)
    finally:
        dataset.finalize()
    return {"episodes": len(checked.sequences), "frames": total, "robot_type": robot_type,
            "lerobot": lerobot_version()}


def export_lerobot(dataset_root: str | Path, split: str, out: str | Path, robot_type: str | None = None,
                   repo_id: str = "muble/shopvrb2") -> dict[str, Any]:
    """``check_split`` then ``write_lerobot``."""
    return write_lerobot(check_split(dataset_root, split), out, robot_type, repo_id)
