"""The scene generator's options (a structured config: a mistyped key is an error)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable

from muble.core.ranges import bounded
from muble.stage.camera import DEFAULT_LENS_MM, DEFAULT_POSITION, DEFAULT_ROTATION_DEG
from muble.stage.rest import SETTLED_DISPLACEMENT
from muble.stage.table import STAGES, UNNAMED_STAGE, Stage, stage_named

# The options whose defaults are the stage's (``muble.stage.table.Stage``), each with its value on a stage. The
# defaults are those of the stage a config that names none stands on; an option left at its default follows the
# stage the config names (``on_stage``).
STAGE_OPTIONS: dict[str, Callable[[Stage], Any]] = {
    "reach_x": lambda stage: list(stage.reach[0]),
    "reach_y": lambda stage: list(stage.reach[1]),
    "table_x": lambda stage: list(stage.top[0]),
    "table_y": lambda stage: list(stage.top[1]),
    "margin": lambda stage: stage.object_margin,
    "robot_clearance": lambda stage: stage.robot_clearance,
}
_UNNAMED = STAGES[UNNAMED_STAGE]


@dataclass
class GeneratorConfig:
    """How SHOP-VRB2 scenes are sampled, placed and checked.

    ``count_probabilities`` gives the chance of each object count from ``min_objects`` up (SHOP-VRB2: 47.3% of
    scenes hold 4 objects, 52.7% hold 5). Objects are placed with their base centre inside ``reach_x`` x
    ``reach_y`` (the arm's reachable part of the table, metres in the robot frame) and their whole footprint on
    the table (``table_x`` x ``table_y``), ``robot_clearance`` from the robot's base axis; ``margin`` is the least
    mesh-to-mesh distance between objects. Those six options default to the values of the ``stage`` the scenes
    stand on (``STAGE_OPTIONS``). A layout is kept when every object settles (``muble.stage.rest.settled``, its
    displacement within ``stability_tolerance``) in ``settle_time`` seconds of physics. The scenes' images are the run's
    ``renderer.width`` x ``renderer.height`` (``SceneGenerator``'s ``image_size``); ``min_visible_pixels`` is counted
    on the SHOP-VRB2 camera's 848 x 480 image and scales with the area of another size; the check renders at
    ``occlusion_scale`` of the image. Layouts settle with the physics step of ``robot`` (``robot.timestep``). The
    plugins it uses are named here (``muble_conf/generator/*.yaml`` names them): ``object_set``, the ``renderer``
    that draws the segmentation for the visibility checks and the masks (it gets ``width`` and ``height`` besides
    ``renderer_options`` and is set up with MuJoCo models), and the ``reach_primitive`` asked whether each object
    can be grasped.

    The held-out options move each scene's camera (``camera_jitter_m`` metres per axis, ``camera_jitter_deg``
    degrees per Euler angle) and lamps (``lamp_jitter``: metres per axis, and the energy factor's spread around 1),
    each from a random stream of its own (``muble.generation.staging``); at 0 every scene is as without them.
    ``distractors`` adds that many objects to each scene's drawn count and keeps a scene only when at least that
    many of its objects are in no step's result of the instruction's program (no filter, relation or action of
    the instruction picks them: ``muble.generation.task_mix``); the scene file lists those ids under
    ``extra.generator.distractors``, hidden from agents.

    ``physical_properties`` names hidden physical properties (``muble.core.physical_properties.PROPERTIES``:
    ``friction``, ``com_offset``, ``contents``) to draw for every object the object set says carries them
    (``ObjectSet.physical_properties``), each from a random stream of its own; the built models have them in every
    check and the scene file holds them (``SceneObject.extra``), hidden from agents. Empty: none is drawn or written.
    """

    object_set: str = ""
    object_set_options: dict[str, Any] = field(default_factory=dict)
    renderer: str = ""
    renderer_options: dict[str, Any] = field(default_factory=dict)
    split: str = "train"
    min_objects: int = bounded(4, ge=1)
    count_probabilities: list[float] = bounded(default_factory=lambda: [0.473, 0.527], ge=0, each=True)
    reach_x: list[float] = field(default_factory=lambda: STAGE_OPTIONS["reach_x"](_UNNAMED))
    reach_y: list[float] = field(default_factory=lambda: STAGE_OPTIONS["reach_y"](_UNNAMED))
    # The stage the scenes stand on (muble.stage.table.STAGES), and so every episode of them. Each scene file names
    # it as its "stage" key, except robosuite's, which a file without the key stands on (None: that one too), so
    # protocol shopvrb2_v1's files keep their bytes (the protocol pins robosuite's).
    stage: str | None = None
    table_x: list[float] = field(default_factory=lambda: STAGE_OPTIONS["table_x"](_UNNAMED))
    table_y: list[float] = field(default_factory=lambda: STAGE_OPTIONS["table_y"](_UNNAMED))
    margin: float = bounded(STAGE_OPTIONS["margin"](_UNNAMED), ge=0)  # m
    robot_clearance: float = STAGE_OPTIONS["robot_clearance"](_UNNAMED)  # m from the robot's base axis
    min_weight_gap: float = 5.0  # g
    min_visible_pixels: int = 200
    occlusion_scale: float = bounded(1.0, gt=0, le=1)
    masks: bool = True
    stability: bool = True
    settle_time: float = 1.0  # s
    stability_tolerance: float = SETTLED_DISPLACEMENT  # m
    # Accept a layout only when every stack its instruction's ground truth builds stands upright in physics
    # (``checks.stacks_stand``); the pairs come from the caller (``SceneGenerator.generate(stacks=...)``).
    stack_check: bool = True
    # Accept a layout only when ``robot`` (RobotConfig fields; empty: Panda) can grasp every pickupable object and
    # put it down again (``muble.generation.reachability``).
    reach_check: bool = True
    robot: dict[str, Any] = field(default_factory=dict)
    reach_primitive: str = ""
    placement_tries: int = bounded(60, ge=1)  # positions tried per object before the layout is restarted
    layout_tries: int = bounded(25, ge=1)  # layouts (fresh samples) tried per scene before giving up
    scene_samples: int = 200  # scene samples (of layout_tries layouts each) tried per index to suit its template
    camera_position: list[float] = field(default_factory=lambda: list(DEFAULT_POSITION))
    camera_rotation: list[float] = field(default_factory=lambda: list(DEFAULT_ROTATION_DEG))  # Blender EulerXYZ
    lens_mm: float = DEFAULT_LENS_MM
    camera_jitter_m: float = bounded(0.0, ge=0, hint="m, 0 = none")  # uniform per axis
    camera_jitter_deg: float = bounded(0.0, ge=0, hint="degrees, 0 = none")  # uniform per EulerXYZ angle
    lamp_jitter: float = bounded(0.0, ge=0, hint="m, 0 = none")  # per axis; energy factor in [1 - j, 1 + j]
    distractors: int = bounded(0, ge=0)  # objects beyond the drawn count that the instruction must not refer to
    physical_properties: list[str] = field(default_factory=list)  # hidden properties drawn per object; [] = none


def on_stage(cfg: GeneratorConfig) -> GeneratorConfig:
    """``cfg`` with each of ``STAGE_OPTIONS`` that is left at its default set to the value of the stage ``cfg``
    names; an unknown stage raises ``ConfigError`` listing the stages."""
    stage = stage_named(cfg.stage or UNNAMED_STAGE, "generator.stage")
    changes = {}
    for name, value in STAGE_OPTIONS.items():
        current = getattr(cfg, name)
        if (list(current) if isinstance(value(_UNNAMED), list) else current) == value(_UNNAMED):
            changes[name] = value(stage)
    return dataclasses.replace(cfg, **changes)


def register_generator_config() -> None:
    """Store the schema as ``generator/generator_schema`` so ``muble_conf/generator/*.yaml`` can extend it."""
    from hydra.core.config_store import ConfigStore

    ConfigStore.instance().store(group="generator", name="generator_schema", node=GeneratorConfig)
