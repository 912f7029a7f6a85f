"""benchmarks/original_look.py and the studio look: an original demo scene rendered here is scored against the
file's own masks and frame, and the camera sees the original's light backdrop, not the sky."""
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

from muble.core.types import SEG_BACKGROUND
REPO_ROOT = Path(__file__).resolve().parents[2]
BENCHMARK = REPO_ROOT / "benchmarks" / "original_look.py"


def _benchmark():
    spec = importlib.util.spec_from_file_location("original_look", BENCHMARK)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(BENCHMARK), *args], capture_output=True, text=True, timeout=120,
                          cwd=REPO_ROOT)


def test_bad_reference_input_is_refused_with_a_reason(tmp_path):
    missing = _run("--reference", str(tmp_path / "nowhere"))
    assert missing.returncode == 2 and "no such folder" in missing.stderr
    empty = _run("--reference", str(tmp_path))
    assert empty.returncode == 2 and "NS_AP_demo_scenes.json missing" in empty.stderr
    (tmp_path / "NS_AP_demo_scenes.json").write_text(json.dumps(
        {"info": {}, "scenes": [{"image_index": 0, "image_filename": "a.png", "objects": []}]}))
    (tmp_path / "images").mkdir()
    from PIL import Image

    Image.new("RGB", (8, 8)).save(tmp_path / "images" / "a.png")
    unknown = _run("--reference", str(tmp_path), "--scenes", "0,7")
    assert unknown.returncode == 2 and "scene index [7]" in unknown.stderr and "[0]" in unknown.stderr
    assert _run("--scenes", "one").returncode == 2


@pytest.mark.blender
def test_a_reference_scene_is_scored_and_shows_the_studio_backdrop(reference_dir):
    benchmark = _benchmark()
    (scene, frame_path), = benchmark.reference_scenes(reference_dir, [0])
    options = dict(width=106, height=60, samples=2, denoise=False, segmentation=True)
    rgb, segmentation, _ = benchmark.render_scene(scene, "shopvrb2", options)
    sky_rgb, _, _ = benchmark.render_scene(scene, "shopvrb2", dict(options, backdrop="sky"))
    original = benchmark._original_frame(frame_path, (106, 60))
    scores = benchmark.compare(scene, original, rgb, segmentation)
    assert len(scores["objects"]) == len(scene.objects)
    assert 0.3 < scores["table_iou"] < 1.0 and 0.2 < scores["robot_iou"] < 1.0
    assert all(0.0 <= o["iou"] <= 1.0 and o["ciede2000"] >= 0.0 for o in scores["objects"])
    # The backdrop: about as light as the original's (mean ~160 of 255), a stop above the sky it replaces.
    background = segmentation == SEG_BACKGROUND
    assert background.mean() > 0.2
    studio, sky = rgb[background].mean(), sky_rgb[background].mean()
    assert studio > sky + 20, (studio, sky)
    assert abs(studio - original[background].mean()) < 15
    # A frame scored against itself: SSIM 1 and no colour difference, so the plumbing compares like with like.
    itself = benchmark.compare(scene, rgb, rgb, segmentation)
    assert itself["ssim"] == pytest.approx(1.0)
    assert all(o["ciede2000"] in (0.0, None) for o in itself["objects"])


def test_unknown_backdrop_and_colour_space_are_refused():
    from muble import ConfigError
    from muble_plugins.renderers.blender import BlenderRenderer

    with pytest.raises(ConfigError, match="backdrop"):
        BlenderRenderer(backdrop="cyclorama")
    with pytest.raises(ConfigError, match="colour space"):
        BlenderRenderer(object_colours="cmyk")
