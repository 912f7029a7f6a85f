"""The attribute recogniser (muble_plugins.learned.recogniser): crops from a generated dataset, training through
`muble train`, loading, recognising a masks-mode observation, determinism, and bad data roots."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from muble.core.errors import ConfigError  # noqa: E402
from muble.core.training import TrainingRun  # noqa: E402
from muble_plugins.learned import checkpoint as ckpt  # noqa: E402
from muble_plugins.learned.recogniser import (  # noqa: E402
    AFFORDANCES,
    ATTRIBUTES,
    AttributeRecogniser,
    RecogniserTrainer,
    load_dataset_crops,
    object_crop,
    sizes_from_table,
)

TINY = {"epochs": 1, "crop_size": 16, "batch_size": 8, "validation_fraction": 0.25}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """Four scenes written by `muble generate` with the cheapest settings: no episode, no rest or reach check,
    a small MuJoCo image without shadows (the masks are drawn at the image's size). In a process of its own:
    torch's deterministic mode imports its compiler, which crashed in a process that had rendered with EGL."""
    root = tmp_path_factory.mktemp("recogniser") / "data"
    done = subprocess.run(
        [sys.executable, "-m", "muble.app.cli", "generate", f"dataset.root={root}", "dataset.splits=[train]",
         "dataset.sizes=[4]", "dataset.sequences=false", "dataset.executor=serial",
         "dataset.templates=[move_single]", "generator.reach_check=false", "generator.stability=false",
         "generator.stack_check=false", "renderer.width=160", "renderer.height=120", "renderer.shadows=false"],
        capture_output=True, text=True, env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")})
    assert done.returncode == 0, done.stderr[-2000:]
    return root


def _train(data_root, out_dir, seed=0, **settings):
    run = TrainingRun(out_dir=out_dir, seed=seed, progress=False, threads=1, data_root=data_root)
    return RecogniserTrainer(**{**TINY, **settings}).train(run)


def _masks_observation(data_root):
    """A masks-mode observation of the dataset's first scene, as `muble eval` would show it."""
    from PIL import Image

    from muble.core.types import SEG_BACKGROUND, Frame, Observation
    from muble.episode.modes import ObservationView
    from muble.io.scene_io import load_scene
    from muble_plugins.learned.recogniser import decode_mask

    scene_path = sorted((data_root / "train" / "scenes").glob("*.json"))[0]
    scene = load_scene(scene_path)
    rgb = np.asarray(Image.open(data_root / "train" / "images" / f"{scene_path.stem}.png").convert("RGB"))
    segmentation = np.full(rgb.shape[:2], SEG_BACKGROUND, np.int32)
    for obj in scene.objects:
        segmentation[decode_mask(obj.mask, rgb.shape[:2])] = obj.id
    observation = Observation(scene=scene, images={"front": Frame("front", rgb, segmentation=segmentation)})
    return ObservationView("masks")(observation), scene


def test_cli_round_trip_then_load_and_recognise(dataset, tmp_path):
    from muble.app.cli import main

    out = tmp_path / "run"
    assert main(["train", "trainer=recogniser", f"train.data_root={dataset}", f"train.out_dir={out}",
                 "trainer.epochs=1", "trainer.crop_size=16", "trainer.batch_size=8",
                 "trainer.validation_fraction=0.25", "train.threads=1", "train.progress=false"]) == 0
    figures = json.loads((out / "train.json").read_text())["figures"]
    assert figures["train_crops"] > 0 and figures["validation_scenes"] == 1
    assert figures["data_seconds"] >= 0 and figures["train_seconds"] > 0
    for a in ATTRIBUTES:
        assert 0.0 <= figures[f"val_accuracy_{a}"] <= 1.0

    recogniser = AttributeRecogniser.load(out / "recogniser.pt")
    assert recogniser.extra["size_table"]  # (name, extents) -> size, from the training crops
    observation, scene = _masks_observation(dataset)
    assert all(o.name is None for o in observation.scene.objects)  # masks mode withholds the words
    found = recogniser.recognise(observation)
    assert found and set(found) <= {o.id for o in scene.objects}
    for words in found.values():
        assert set(words) == set(ATTRIBUTES) | set(AFFORDANCES)
        for a in ATTRIBUTES:
            assert words[a] in recogniser.vocabularies[a]
        # affordances are those the training data pairs the predicted name with
        assert [words[k] for k in AFFORDANCES] == [recogniser.affordances[words["name"]][k] for k in AFFORDANCES]

    crops = load_dataset_crops(dataset, 16)
    predicted = recogniser.predict(crops)
    assert all(len(predicted[a]) == len(crops) for a in ATTRIBUTES)


def test_same_seed_same_weights(dataset, tmp_path):
    _train(dataset, tmp_path / "a")
    _train(dataset, tmp_path / "b")
    a, b = (ckpt.load(tmp_path / k / "recogniser.pt", "recogniser")["state"]["model"] for k in "ab")
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def test_a_stopped_run_resumes_to_the_weights_of_an_unstopped_one(dataset, tmp_path, stop_at_next_checkpoint):
    """Two epochs at once, and one epoch, stop, one more: the same weights (the learning-rate schedule, the
    optimiser and the random streams all resume where they stopped)."""
    _train(dataset, tmp_path / "whole", epochs=2)
    go_on = stop_at_next_checkpoint()
    with pytest.raises(KeyboardInterrupt):
        _train(dataset, tmp_path / "stopped", epochs=2)
    go_on()
    stopped = ckpt.load(tmp_path / "stopped" / "recogniser.pt", "recogniser")
    assert stopped["epoch"] == 1 and stopped["state"]["schedule"]["last_epoch"] > 0
    _train(dataset, tmp_path / "stopped", epochs=2)
    whole, resumed = (ckpt.load(tmp_path / k / "recogniser.pt", "recogniser")["state"] for k in ("whole", "stopped"))
    assert all(torch.equal(whole["model"][k], resumed["model"][k]) for k in whole["model"])


def test_cosine_schedule_warms_up_then_decays_to_zero_and_constant_keeps_the_rate():
    from muble_plugins.learned.recogniser import learning_rate_schedule

    rates = {}
    for kind in ("cosine", "constant"):
        optimiser = torch.optim.SGD([torch.nn.Parameter(torch.zeros(1))], lr=0.1)
        schedule = learning_rate_schedule(torch, optimiser, kind, crops=100, batch_size=10, epochs=5)  # 50 steps
        seen = []
        for _ in range(50):
            seen.append(optimiser.param_groups[0]["lr"])
            optimiser.step()
            schedule.step()
        rates[kind] = seen + [optimiser.param_groups[0]["lr"]]
    cosine = rates["cosine"]
    assert cosine[0] < cosine[4] <= 0.1 + 1e-12  # warm-up over the first tenth
    assert max(cosine) == pytest.approx(0.1, rel=0.02)
    assert all(a >= b for a, b in zip(cosine[5:], cosine[6:]))  # then only down
    assert cosine[-1] == pytest.approx(0.0, abs=1e-12)
    assert rates["constant"] == [0.1] * 51


def test_unknown_schedule_is_refused_before_any_data_is_read(tmp_path):
    with pytest.raises(ConfigError, match="trainer.schedule must be one of cosine, constant"):
        RecogniserTrainer(schedule="step")


def test_bad_data_root_is_one_clear_error(tmp_path, capsys):
    from muble.app.cli import main

    empty = tmp_path / "empty"
    empty.mkdir()
    for root in (empty, tmp_path / "missing"):
        assert main(["train", "trainer=recogniser", f"train.data_root={root}", f"train.out_dir={tmp_path / 'o'}",
                     "train.progress=false"]) == 2
        err = capsys.readouterr().err
        assert "muble generate" in err and str(root.name) in err
    assert main(["train", "trainer=recogniser", f"train.out_dir={tmp_path / 'o'}", "train.progress=false"]) == 2
    assert "train.data_root" in capsys.readouterr().err


def test_crop_is_square_around_the_mask_with_its_geometry():
    rgb = np.zeros((40, 80, 3), np.uint8)
    rgb[10:20, 60:80] = 200
    mask = np.zeros((40, 80), bool)
    mask[10:20, 60:80] = True  # touches the right border: the crop is padded there
    crop, geometry = object_crop(rgb, mask, 16)
    assert crop.shape == (4, 16, 16) and crop.dtype == np.uint8
    assert crop[3].max() == 255 and crop[3, 0].max() == 0  # the mask channel, empty above the object
    assert np.allclose(geometry[:4], [60 / 80, 10 / 40, 1.0, 20 / 40])
    assert object_crop(rgb, np.zeros_like(mask), 16) is None


def test_size_comes_from_the_nearest_extents_of_the_predicted_name():
    table = [["bowl", [0.128, 0.128, 0.055], "small"], ["bowl", [0.15, 0.15, 0.065], "medium-sized"],
             ["plate", [0.2, 0.2, 0.02], "large"]]
    geometry = np.zeros((3, 8), np.float32)
    geometry[:, 5:] = [[0.149, 0.151, 0.064], [0.13, 0.13, 0.05], [0.13, 0.13, 0.05]]
    assert sizes_from_table(["bowl", "bowl", "mug"], geometry, table) == ["medium-sized", "small", None]
