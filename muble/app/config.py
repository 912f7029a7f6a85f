"""Structured config schemas and Hydra plumbing.

Config groups mirror the interfaces. Each plugin option's schema comes from its registry record (the record's
``config`` dataclass plus a ``name`` field) and is stored in the ConfigStore as ``<group>/<name>_schema``, so a
yaml file for it extends the schema and a mistyped key is an error, not a silent new key.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING

from muble.core.environment import ROBOT_DEFAULTS
from muble.core.ranges import bounded
from muble.core.types import ObservationMode, Track
from muble.episode.components import GROUP_OF_KIND
from muble.episode.loop import DEFAULT_MAX_STEPS
from muble.io.instructions_io import SHOPVRB2_TEMPLATES
from muble.plugins.registry import Registry
from muble.sim.sensor_noise import WristNoise

HYDRA_VERSION_BASE = "1.3"
CONFIG_MODULE = "muble_conf"


@dataclass
class RobotConfig:
    """A robosuite single-arm robot and its gripper and controller."""

    name: str = MISSING  # robosuite robot name: Panda, Sawyer, UR5e, Kinova3, IIWA
    # The defaults are ``muble.core.environment.ROBOT_DEFAULTS``, which an environment built with no robot config uses.
    gripper: str | None = ROBOT_DEFAULTS["gripper"]  # robosuite gripper name; None = the robot's default
    # End-effector deltas by IK to joint servos; "OSC_POSE": its old name.
    controller: str = ROBOT_DEFAULTS["controller"]
    control_freq: float = bounded(ROBOT_DEFAULTS["control_freq"], gt=0)  # Hz
    timestep: float = bounded(ROBOT_DEFAULTS["timestep"], gt=0)  # s, MuJoCo physics step
    grasp: str = ROBOT_DEFAULTS["grasp"]  # "weld" (attach on contact of all pads) or "friction"


@dataclass
class SensorsConfig:
    """Which sensor plugins run: registry name -> that sensor's options (a mapping, so configs can add to it)."""

    enabled: dict[str, Any] = field(default_factory=dict)


@dataclass
class DisturbancesConfig:
    """Which disturbance plugins act during episodes: registry name -> its options (a mapping, like sensors; empty:
    the world never pushes back)."""

    enabled: dict[str, Any] = field(default_factory=dict)
    # How many of the enabled disturbances that apply to an episode's instruction act in it, drawn per episode
    # (stream episode.disturbance_mix) from [low, high]; empty: every one that applies.
    per_episode: list[int] = bounded(default_factory=list, ge=0, each=True)


@dataclass
class NoiseConfig(WristNoise):
    """How the wrist force/torque sensor errs while episodes run (``muble.sim.sensor_noise``): white noise per
    output sample and a bias that drifts, for force and torque; all zero (``noise=none``): a perfect sensor."""


@dataclass
class OutputConfig:
    dir: str = "${hydra:runtime.output_dir}"
    gif: bool = True


class ActionNameStyle(str, Enum):
    """How sequence files name the primitives (``muble.io.action_names``)."""

    registry = "registry"
    original = "original"


@dataclass
class EpisodeConfig:
    """The action loop's limits and what is rendered after every primitive."""

    max_steps: int = bounded(DEFAULT_MAX_STEPS, ge=1)
    cameras: list[str] = field(default_factory=lambda: ["front"])
    # Primitive names in sequence files: "registry" (move, approach, close_gripper, lift, weigh, lower …) or
    # "original" (the original MuBlE's move, approach_grasp, grasp, pick_up, put_down, release).
    action_names: ActionNameStyle = ActionNameStyle.registry


@dataclass
class DatasetConfig:
    """``muble generate``/``muble eval``: where the dataset lives, its splits, template mix and execution.

    ``splits[k]`` gets ``sizes[k]`` scenes (lists, so an override replaces them: ``dataset.splits=[val]
    dataset.sizes=[20]``). Indices ``start .. start + size - 1`` of each split are produced, those with
    ``index % num_shards == shard`` by this run. Re-running with the same ``root`` resumes: finished indices
    are skipped.
    """

    root: str = "${hydra:runtime.output_dir}/dataset"
    splits: list[str] = field(default_factory=lambda: ["train", "val", "test"])
    sizes: list[int] = bounded(default_factory=lambda: [10000, 1000, 1000], ge=0, each=True)  # the paper's
    start: int = bounded(0, ge=0)
    shard: int = bounded(0, ge=0)
    num_shards: int = bounded(1, ge=1)
    templates: list[str] = field(default_factory=lambda: list(SHOPVRB2_TEMPLATES))
    template_weights: list[float] = bounded(default_factory=list, ge=0, each=True)  # empty = uniform
    # Options every task of the mix is generated with (its config's fields, e.g. a SHOP-VRB2 task's weight_margin_g);
    # empty: each task's defaults
    task_options: dict[str, Any] = field(default_factory=dict)
    sequences: bool = True  # run the oracle with physics for ground-truth sequences and keyframes
    gif: bool = False
    executor: str = "processes"  # serial | processes | ray
    workers: int = bounded(2, ge=1)
    ray_address: str | None = None  # executor=ray: an existing cluster to join; None = a private local cluster
    # muble eval on files in the original SHOP-VRB2 layout instead of a generated dataset folder (both or neither;
    # scenes_file: a combined {info, scenes} file, a single scene or a folder of scene files).
    scenes_file: str | None = None
    instructions_file: str | None = None


@dataclass
class EvaluationConfig:
    """``muble eval``: how the agent's episodes run (the dataset, splits and executor come from ``dataset``)."""

    render: bool = False  # render a keyframe after every primitive with the configured renderer (slower)
    keyframes: bool = False  # with render: also write the keyframes of every episode as PNGs
    limit: int = bounded(0, ge=0)  # evaluate at most this many indices per split (the first ones); 0 = all
    plot: bool = True  # write the success bar chart per split
    # s one decision of the agent (a call of its reset or act) may take; one that takes longer ends its episode as
    # timeout and the evaluation goes on (muble.episode.loop.AgentCalls). 0: no limit.
    decision_timeout: float = bounded(0.0, ge=0)


@dataclass
class BenchmarkConfig:
    """Which protocol, track and observation mode a run follows; stamped on every report."""

    protocol: str | None = None  # set by protocol=NAME (muble_conf/protocol): the protocol results are labelled with
    split: str = "mini"  # with a protocol: the protocol split `muble generate` writes
    track: Track = Track.program
    mode: ObservationMode = ObservationMode.graph


@dataclass
class TrainConfig:
    """``muble train``: where the part's checkpoints go and how the run goes (the part is ``trainer=NAME``)."""

    out_dir: str | None = None  # None: the run's output folder (output.dir)
    resume: bool = True  # go on from the last checkpoint in out_dir (refused if it was made under another config)
    progress: bool = True
    threads: int = bounded(0, ge=0)  # CPU threads for training; 0: the library's default
    data_root: str | None = None  # a `muble generate` dataset folder, for trainers that learn from its renders


@dataclass
class MubleConfig:
    """The top-level schema of every MuBlE application."""

    robot: RobotConfig = MISSING
    renderer: Any = MISSING
    planner: Any = MISSING
    task: Any = MISSING
    objects: Any = MISSING
    sensors: SensorsConfig = MISSING
    agent: Any = MISSING
    generator: Any = MISSING
    disturbances: DisturbancesConfig = field(default_factory=DisturbancesConfig)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    episode: EpisodeConfig = field(default_factory=EpisodeConfig)
    dataset: DatasetConfig = field(default_factory=DatasetConfig)
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    benchmark: BenchmarkConfig = field(default_factory=BenchmarkConfig)
    trainer: Any = None  # `muble train`: the learned part to train (trainer=NAME, a registered trainer)
    train: TrainConfig = field(default_factory=TrainConfig)
    protocol: Any = None  # the frozen protocol's splits (muble_conf/protocol, muble.dataset.protocol), or none
    seed: int = bounded(0, ge=0)  # numpy seeds are non-negative
    scene_index: int = bounded(0, ge=0)
    # muble run, the Gymnasium environments, muble serve: with a split name, scene_index is that split's index as
    # muble generate makes it (the split's seed, its protocol settings and template mix); none: the configured
    # task on scene scene_index of the generator seeded with seed.
    split: str | None = None
    dry_run: bool = False  # build every configured plugin and write the manifest, but run nothing
    output: OutputConfig = field(default_factory=OutputConfig)


def _schema_with_name(config: type, name: str) -> type:
    fields = [("name", str, dataclasses.field(default=name))]
    return dataclasses.make_dataclass(f"{config.__name__}WithName", fields, bases=(config,))


def register_configs(registry: Registry) -> None:
    """Store the top-level schema and every registered plugin's schema in Hydra's ConfigStore."""
    from muble.generation.config import register_generator_config

    cs = ConfigStore.instance()
    cs.store(name="muble_schema", node=MubleConfig)
    register_generator_config()
    cs.store(group="robot", name="robot_schema", node=RobotConfig)
    cs.store(group="sensors", name="sensors_schema", node=SensorsConfig)
    cs.store(group="disturbances", name="disturbances_schema", node=DisturbancesConfig)
    cs.store(group="noise", name="noise_schema", node=NoiseConfig)
    for kind, group in GROUP_OF_KIND.items():
        for name in registry.names(kind):
            record = registry.get(kind, name).record
            if record.config is not None:
                cs.store(group=group, name=f"{name}_schema", node=_schema_with_name(record.config, name))
    for name in registry.names("trainer"):
        record = registry.get("trainer", name).record
        if record.config is not None:
            cs.store(group="trainer", name=f"{name}_schema", node=_schema_with_name(record.config, name))


def searchpath_override(registry: Registry) -> list[str]:
    """The ``hydra.searchpath`` override that adds every plugin's config folders (empty list if none)."""
    if not registry.searchpath:
        return []
    return ["hydra.searchpath=[" + ",".join(registry.searchpath) + "]"]


def compose(config_name: str = "run", overrides: list[str] | tuple[str, ...] = (), registry: Registry | None = None):
    """Compose a config with Hydra's compose API, plugins' config folders included (for tests and notebooks)."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_module

    from muble.plugins.registry import get_registry

    registry = registry or get_registry()
    register_configs(registry)
    with initialize_config_module(config_module=CONFIG_MODULE, version_base=HYDRA_VERSION_BASE):
        return hydra_compose(config_name=config_name, overrides=[*overrides, *searchpath_override(registry)])
