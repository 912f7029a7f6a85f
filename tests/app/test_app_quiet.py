"""Quiet by default: robosuite's and PyOpenGL's messages about optional parts MuBlE does not use are dropped,
and `--verbose` keeps them."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

IMPORT_ROBOSUITE = "from muble.quiet import quiet_third_party; quiet_third_party({verbose}); import robosuite"


@pytest.mark.parametrize("verbose", [False, True])
def test_robosuite_import_noise_only_when_verbose(verbose):
    result = subprocess.run([sys.executable, "-c", IMPORT_ROBOSUITE.format(verbose=verbose)], capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    noisy = "private macro file" in result.stderr or "robosuite_models" in result.stderr
    assert noisy == verbose, result.stderr


def test_verbose_flag_is_taken_out_of_the_command_line(tmp_path):
    from tests.app.usage_probe import run_many

    (result,) = run_many([["--verbose", "plugins", "--kind", "renderer"]], tmp_path)
    assert result["code"] == 0 and "mujoco" in result["stdout"], result


@pytest.mark.blender
def test_blender_render_prints_only_its_result(tmp_path):
    scene = Path(__file__).resolve().parents[1] / "planning" / "data" / "glass_beside_a_tall_thermos.json"
    result = subprocess.run([sys.executable, "-m", "muble.app.cli", "render", str(scene), "--set", "width=96",
                             "--set", "height=64", "--set", "samples=1", "--out", str(tmp_path / "r")],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    assert result.stdout.strip().splitlines() == [f"rendered 1 keyframe(s) of {scene} to {tmp_path / 'r'}"]
    assert result.stderr.strip() == "", result.stderr[-3000:]


# What a third-party message looks like in the output: robosuite's prefix, a Python warning, PyOpenGL's and
# nanobind's (OMPL's bindings) notes at exit.
THIRD_PARTY_LINE = re.compile(r"robosuite|Warning:|OpenGL|nanobind|leaked|mink")


def _muble(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "HYDRA_FULL_ERROR": "0", "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    env.pop("MUBLE_VERBOSE", None)
    return subprocess.run([sys.executable, "-m", "muble.app.cli", *args], capture_output=True, text=True, env=env,
                          timeout=600)


@pytest.mark.slow
def test_generate_and_eval_with_two_workers_print_no_third_party_line(tmp_path):
    root = tmp_path / "ds"
    generate = _muble("generate", "dataset.splits=[val]", "dataset.sizes=[2]", f"dataset.root={root}",
                      "dataset.sequences=false", "dataset.executor=processes", "dataset.workers=2",
                      "dataset.templates=[measure_weight_single]", "renderer.width=96", "renderer.height=64",
                      f"hydra.run.dir={tmp_path / 'gen'}")
    assert generate.returncode == 0, generate.stderr[-2000:]
    evaluate = _muble("eval", f"dataset.root={root}", f"hydra.run.dir={tmp_path / 'eval'}", "agent=oracle",
                      "dataset.executor=processes", "dataset.workers=2")
    assert evaluate.returncode == 0, evaluate.stderr[-2000:]
    for result in (generate, evaluate):
        lines = (result.stdout + result.stderr).splitlines()
        assert lines, "the command printed nothing at all"
        noisy = [line for line in lines if THIRD_PARTY_LINE.search(line)]
        assert not noisy, noisy
