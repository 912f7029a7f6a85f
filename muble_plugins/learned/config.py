"""The learned parts' settings (``muble_conf/trainer/*.yaml``, ``muble_conf/agent/learned_planner.yaml``).

Kept apart from the models so that listing the plugins, or composing a config, needs no PyTorch.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from muble.core.ranges import bounded
from muble.io.instructions_io import SHOPVRB2_TEMPLATES

# The templates the trainers write instructions for: the ten SHOP-VRB2 templates, in their overall order.
TEMPLATES = SHOPVRB2_TEMPLATES


@dataclass
class PlannerTrainerConfig:
    """``muble train trainer=planner``: the planner learns from the oracle's roll-outs in the symbolic world."""

    scenes: int = bounded(2000, ge=1)  # training scenes (each gives one instruction per template it suits)
    # Passes over the ~250,000 labelled states of 2,000 scenes; validation accuracy stops changing after 2 or 3.
    epochs: int = bounded(5, ge=1)
    batch_size: int = bounded(256, ge=1)
    learning_rate: float = bounded(1e-3, gt=0)
    width: int = bounded(32, ge=4)  # the Transformer encoder's width (NS-AP: 32)
    heads: int = bounded(2, ge=1)
    layers: int = bounded(2, ge=1)
    # Share of roll-out steps where a random primitive is taken instead of the oracle's (the oracle labels the
    # state it leads to), so the planner learns to recover from states the oracle never visits.
    explore: float = bounded(0.2, ge=0, le=1)
    # Share of roll-out primitives that fail without effect, as a physical one may (a missed grasp, no plan).
    slip: float = bounded(0.05, ge=0, lt=1)
    validation_scenes: int = bounded(200, ge=0)
    # The templates whose instructions the roll-outs play, by template id ([]: the ten SHOP-VRB2 templates); the
    # scenes carry every hidden property, so any registered family can be named (e.g. the physical family).
    templates: list[str] = field(default_factory=list)


@dataclass
class ParserTrainerConfig:
    """``muble train trainer=parser``: instruction text to program, on generated (text, program) pairs."""

    scenes: int = bounded(2000, ge=1)  # training scenes (each gives one instruction per template it suits)
    # Passes over the ~15,000 pairs of 2,000 scenes: 4 parse 99.8% of the test split exactly (docs/learned.md).
    epochs: int = bounded(4, ge=1)
    batch_size: int = bounded(64, ge=1)
    learning_rate: float = bounded(1e-3, gt=0)  # peak; warm-up, then cosine decay to zero at the last epoch
    width: int = bounded(128, ge=8)  # the encoder-decoder Transformer's width (a multiple of heads)
    heads: int = bounded(4, ge=1)
    layers: int = bounded(2, ge=1)  # encoder layers, and as many decoder layers
    feedforward: int = bounded(256, ge=8)  # each layer's feed-forward width
    dropout: float = bounded(0.1, ge=0, lt=1)
    validation_scenes: int = bounded(200, ge=0)  # scenes of a seed stream disjoint from the training scenes'
    # The registered object set whose words the scenes carry (e.g. "ycb" for the YCB scenes' names and colours).
    object_set: str = "shopvrb2"


@dataclass
class RecogniserTrainerConfig:
    """``muble train trainer=recogniser``: ResNet-18 (random initialisation) from object crops to attributes."""

    scenes: int = bounded(2000, ge=1)
    epochs: int = bounded(12, ge=1)
    batch_size: int = bounded(64, ge=1)
    learning_rate: float = bounded(1e-3, gt=0)  # peak (schedule "cosine") or throughout (schedule "constant")
    # "cosine": a short linear warm-up, then cosine decay to zero at the last epoch, so the last epoch's weights
    # are a settled model rather than one step of a noisy walk; "constant": the learning rate throughout.
    schedule: str = "cosine"
    # Pixels of the square crop the network sees (a training step costs about 9.5, 12.7 and 16 ms a crop at 32, 48
    # and 64 on two cores). 48 keeps the highlights that tell ceramic from plastic in a 320x240 frame's objects.
    crop_size: int = bounded(48, ge=16)
    renderers: list[str] | None = None  # images of which renderers to learn from (None: every one in the data)
    validation_fraction: float = bounded(0.1, ge=0, lt=1)


@dataclass
class LearnedPlannerConfig:
    """``agent=learned_planner``: a trained planner; on the language track a trained parser gives it the program,
    in masks mode a trained recogniser gives it the objects' attributes."""

    checkpoint: str = "planner.pt"
    parser: str | None = None  # parser checkpoint (needed on the language track)
    recogniser: str | None = None  # recogniser checkpoint (needed in masks mode)
