"""Learned parts in the style of NS-AP (Nazarczuk et al.): a planner that picks the next primitive and its target,
an instruction parser (text to program) and an attribute recogniser (object crop to name, colour, material,
shape, size), each trained by ``muble train trainer=NAME``, and the ``learned_planner`` agent that uses them.

Needs PyTorch (``pip install "muble[learn]"``): the models' modules load only when the registry builds a part,
so listing plugins and composing configs work without it.
"""
import os
import sys

from muble import PluginRecord, hookimpl

# The learned parts run PyTorch on the CPU. PyTorch's CUDA wheels import Triton (a GPU kernel compiler) when an
# optimiser is made, and Triton's bundled LLVM clashes with the LLVM that Mesa's software rasteriser loads for
# an EGL context: a process that has rendered with MuJoCo (an evaluation, the test suite) ends in a segmentation
# fault. Marking Triton absent makes PyTorch go without it (CPU kernels need none). MUBLE_ALLOW_TRITON=1 lifts it,
# for a process that renders on a GPU and compiles with Triton.
if os.environ.get("MUBLE_ALLOW_TRITON") != "1":
    sys.modules.setdefault("triton", None)

from muble_plugins.learned.config import (
    LearnedPlannerConfig,
    ParserTrainerConfig,
    PlannerTrainerConfig,
    RecogniserTrainerConfig,
)


# The registry's factories: each gets its checked config and imports its part's module only when called.
def planner_trainer(config: PlannerTrainerConfig):
    from muble_plugins.learned.planner import PlannerTrainer

    return PlannerTrainer(config)


def parser_trainer(config: ParserTrainerConfig):
    from muble_plugins.learned.parser import ParserTrainer

    return ParserTrainer(config)


def recogniser_trainer(config: RecogniserTrainerConfig):
    from muble_plugins.learned.recogniser import RecogniserTrainer

    return RecogniserTrainer(config)


def learned_planner(config: LearnedPlannerConfig):
    from muble_plugins.learned.agent import LearnedPlannerAgent

    return LearnedPlannerAgent(config)


@hookimpl
def muble_register_trainers() -> list[PluginRecord]:
    return [
        PluginRecord("planner", planner_trainer, "the next primitive and its target, from symbolic roll-outs",
                     PlannerTrainerConfig, takes_config=True),
        PluginRecord("parser", parser_trainer, "instruction text to program (sequence to sequence)",
                     ParserTrainerConfig, takes_config=True),
        PluginRecord("recogniser", recogniser_trainer, "object crop to name, colour, material, shape, size "
                     "(ResNet-18)", RecogniserTrainerConfig, takes_config=True),
    ]


@hookimpl
def muble_register_agents() -> list[PluginRecord]:
    return [PluginRecord("learned_planner", learned_planner, "a trained planner (with a trained parser on the "
                         "language track and a trained recogniser in masks mode)", LearnedPlannerConfig,
                         takes_config=True)]
