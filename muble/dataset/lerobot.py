"""Export generated SHOP-VRB2 sequences as a LeRobot-style dataset (parquet frames + PNG images).

Each episode is one sequence file; each frame is the keyframe after a primitive (frame 0: the start). Per frame:
``observation.state`` (end-effector position, quaternion w x y z, gripper command: 8 floats), ``action`` (the
state the primitive led to: the next frame's state, the last frame repeats its own), ``action.primitive`` and
``action.target`` (the primitive that produced the *next* frame), the measured weight, the instruction as the
task, and the image path. Layout (LeRobot v2.1): ``meta/info.json``, ``meta/episodes.jsonl``,
``meta/tasks.jsonl``, ``data/chunk-000/episode_XXXXXX.parquet``,
``images/observation.images.front/episode_XXXXXX/frame_XXXXXX.png``.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

from muble.core.atomic import write_bytes_atomic
from muble.core.errors import ConfigError, SceneValidationError
from muble.core.layout import DatasetLayout

CODEBASE_VERSION = "v2.1"
IMAGE_KEY = "observation.images.front"
STATE_NAMES = ["x", "y", "z", "qw", "qx", "qy", "qz", "gripper"]


def _state(robot: dict[str, Any]) -> list[float]:
    return [*map(float, robot["pos"]), *map(float, robot["ori"]), float(robot["gripper_action"])]


def _jsonl(rows: list[dict[str, Any]]) -> bytes:
    return "".join(json.dumps(r) + "\n" for r in rows).encode()


def read_sequence(path: Path, split_dir: Path) -> dict[str, Any]:
    """A sequence file, checked for what the export reads: a ``SceneValidationError`` names the file and the
    missing or malformed field (a truncated or hand-edited file), a ``ConfigError`` a missing keyframe image."""
    from muble.core.scene_io import read_json

    sequence = read_json(path)
    try:
        observations = sequence["observations"]
        task = sequence["info"]["instruction"]
        images = sequence["image_paths"]
        if not isinstance(observations, list) or not observations:
            raise TypeError("'observations' must be a non-empty list")
        if not isinstance(images, list) or len(images) != len(observations):
            raise TypeError(f"'image_paths' must list one image per observation ({len(observations)})")
        for i, o in enumerate(observations):
            robot = o["robot"]
            _state(robot), float(robot["weight_measurement"]), robot["action"][0]
    except (KeyError, IndexError, TypeError, ValueError) as e:
        what = f"missing field {e}" if isinstance(e, KeyError) else str(e)
        raise SceneValidationError(f"{path}: not a complete sequence file ({what}); generate the split again "
                                   "or remove the file") from e
    if not isinstance(task, str):
        raise SceneValidationError(f"{path}: 'info.instruction' must be text", field="instruction")
    missing = [p for p in images if not (split_dir / p).is_file()]
    if missing:
        raise ConfigError(f"{path}: {len(missing)} keyframe image(s) missing, first {split_dir / missing[0]}; "
                          "generate the split again")
    return sequence


def export_lerobot(dataset_root: str | Path, split: str, out: str | Path, robot_type: str = "") -> dict[str, int]:
    """Write the split's sequences under ``out``; returns episode and frame counts."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    layout = DatasetLayout(Path(dataset_root), split)
    sequences = sorted((layout.split_dir / "sequences").glob("*.json"))
    if not sequences:
        raise ConfigError(f"no sequence files under {layout.split_dir / 'sequences'}; generate the split with "
                          "dataset.sequences=true first")
    loaded = [read_sequence(path, layout.split_dir) for path in sequences]  # all checked before writing
    out = Path(out)
    tasks: dict[str, int] = {}
    episodes, total = [], 0
    for episode_index, (path, sequence) in enumerate(zip(sequences, loaded)):
        observations = sequence["observations"]
        task = sequence["info"]["instruction"]
        task_index = tasks.setdefault(task, len(tasks))
        states = [_state(o["robot"]) for o in observations]
        rows: dict[str, list] = {k: [] for k in (
            "observation.state", "action", "action.primitive", "action.target", "observation.weight",
            IMAGE_KEY, "timestamp", "frame_index", "episode_index", "index", "task_index")}
        for i, obs in enumerate(observations):
            following = observations[i + 1]["robot"]["action"] if i + 1 < len(observations) else ["STOP", None]
            target = following[1]
            image = Path(sequence["image_paths"][i])
            rel = Path("images") / IMAGE_KEY / f"episode_{episode_index:06d}" / f"frame_{i:06d}.png"
            (out / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(layout.split_dir / image, out / rel)
            rows["observation.state"].append(states[i])
            rows["action"].append(states[min(i + 1, len(states) - 1)])
            rows["action.primitive"].append(following[0])
            rows["action.target"].append(json.dumps(target))
            rows["observation.weight"].append(float(obs["robot"]["weight_measurement"]))
            rows[IMAGE_KEY].append(str(rel))
            rows["timestamp"].append(float(i))
            rows["frame_index"].append(i)
            rows["episode_index"].append(episode_index)
            rows["index"].append(total + i)
            rows["task_index"].append(task_index)
        table = pa.table(rows)
        target_path = out / "data" / "chunk-000" / f"episode_{episode_index:06d}.parquet"
        target_path.parent.mkdir(parents=True, exist_ok=True)
        tmp = target_path.with_name(f".{target_path.name}.tmp")
        pq.write_table(table, tmp)
        tmp.replace(target_path)
        episodes.append({"episode_index": episode_index, "tasks": [task], "length": len(observations),
                         "source": str(path.relative_to(layout.root)), "result": sequence["result"]})
        total += len(observations)
    info = {
        "codebase_version": CODEBASE_VERSION, "robot_type": robot_type, "total_episodes": len(episodes),
        "total_frames": total, "total_tasks": len(tasks), "chunks_size": 1000, "fps": 1,
        "splits": {split: f"0:{len(episodes)}"},
        "data_path": "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet",
        "image_path": "images/{image_key}/episode_{episode_index:06d}/frame_{frame_index:06d}.png",
        "features": {
            "observation.state": {"dtype": "float32", "shape": [8], "names": STATE_NAMES},
            "action": {"dtype": "float32", "shape": [8], "names": STATE_NAMES},
            "action.primitive": {"dtype": "string", "shape": [1]},
            "action.target": {"dtype": "string", "shape": [1]},
            "observation.weight": {"dtype": "float32", "shape": [1]},
            IMAGE_KEY: {"dtype": "image", "shape": None},
            "timestamp": {"dtype": "float32", "shape": [1]},
            "frame_index": {"dtype": "int64", "shape": [1]},
            "episode_index": {"dtype": "int64", "shape": [1]},
            "index": {"dtype": "int64", "shape": [1]},
            "task_index": {"dtype": "int64", "shape": [1]},
        },
        "note": "one frame per primitive action (keyframes), not a fixed control rate",
    }
    write_bytes_atomic(out / "meta" / "info.json", json.dumps(info, indent=2).encode())
    write_bytes_atomic(out / "meta" / "episodes.jsonl", _jsonl(episodes))
    write_bytes_atomic(out / "meta" / "tasks.jsonl",
                       _jsonl([{"task_index": i, "task": t} for t, i in sorted(tasks.items(), key=lambda x: x[1])]))
    return {"episodes": len(episodes), "frames": total}
