"""The language track end to end with real trained parts: a parser and a planner, each trained briefly through
their trainers, play symbolic episodes told only the instruction's text (no program), as ``muble eval
benchmark.track=language agent=learned_planner`` runs them."""
from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from muble import Outcome  # noqa: E402
from muble.core.training import TrainingRun  # noqa: E402
from muble.episode.loop import run_episode  # noqa: E402

from muble_plugins.common.success import check  # noqa: E402
from muble_plugins.common.symbolic import SymbolicWorld  # noqa: E402
from muble_plugins.learned.agent import LearnedPlannerAgent  # noqa: E402
from muble_plugins.learned.parser import ParserTrainer  # noqa: E402
from muble_plugins.learned.planner import PlannerTrainer, instructions_for, scene_for  # noqa: E402


def test_a_trained_parser_and_planner_solve_language_track_episodes(tmp_path):
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        PlannerTrainer(scenes=24, epochs=6, validation_scenes=0, batch_size=64).train(
            TrainingRun(out_dir=tmp_path / "planner", seed=1, progress=False))
        ParserTrainer(scenes=200, epochs=8, validation_scenes=0, width=64, heads=4, layers=1, feedforward=128,
                      learning_rate=6e-3, batch_size=32, dropout=0.0).train(
            TrainingRun(out_dir=tmp_path / "parser", seed=1, progress=False))
        agent = LearnedPlannerAgent(checkpoint=str(tmp_path / "planner" / "planner.pt"),
                                    parser=str(tmp_path / "parser" / "parser.pt"))
        solved = total = 0
        for index in range(4):
            scene = scene_for(1, 100 + index, True)  # scenes neither part trained on
            for instruction in instructions_for(scene, 1, 100 + index, True):
                result = run_episode(instruction, SymbolicWorld(scene), agent, check, track="language")
                total += 1
                solved += result.outcome is Outcome.SUCCESS
    finally:
        torch.set_num_threads(threads)
    assert total >= 20
    # Told no program, the agent parses the text and plans from the parse: without a working parser it would
    # stop at once on every episode (an empty program).
    assert solved >= 0.7 * total, f"{solved}/{total}"


TRAIN_BESIDE_EGL = """
import os, sys
os.environ.setdefault("MUJOCO_GL", "egl")
from muble_plugins.renderers.mujoco.gl import make_context
make_context(32, 32)  # as in an evaluation or the test suite: MuJoCo's renderer already holds an EGL context
from muble.core.training import TrainingRun
from muble_plugins.learned.planner import PlannerTrainer
from pathlib import Path
PlannerTrainer(scenes=2, epochs=1, validation_scenes=0).train(TrainingRun(out_dir=Path(sys.argv[1]), progress=False))
print("trained", flush=True)
"""


@pytest.mark.gl
def test_training_in_a_process_that_renders_with_egl_runs_to_its_end(tmp_path):
    import subprocess
    import sys

    script = tmp_path / "beside_egl.py"
    script.write_text(TRAIN_BESIDE_EGL)
    done = subprocess.run([sys.executable, str(script), str(tmp_path / "run")], capture_output=True, text=True,
                          timeout=600)
    # Triton, imported by torch when an optimiser is made, ended such a process with a segmentation fault (-11).
    assert done.returncode == 0 and "trained" in done.stdout, (done.returncode, done.stderr[-2000:])
