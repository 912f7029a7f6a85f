"""The environment as plugins see it: what a primitive, sensor or renderer may use, and nothing else.

``TabletopEnv`` (``muble.sim.env``) implements it; a primitive receives it in ``execute``/``feasible``, a sensor in
``read``/``reset``/``on_step``. Plugins depend on this protocol only, never on ``muble.sim`` modules. The MuJoCo
model and data are part of it on purpose: a primitive that plans its own motion reads geoms and contacts there.
See docs/plugins.md ("The environment API") for examples.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Protocol, runtime_checkable

import numpy as np

from muble.core.types import Pose, Trajectory

if TYPE_CHECKING:  # pragma: no cover
    import mujoco

    from muble.core.interfaces import CollisionWorld, MotionPlanner
    from muble.core.objects import ObjectModel
    from muble.core.scene import SceneGraph



class EnvironmentNames(Protocol):
    """MuJoCo names of the robot's and the world's parts (``env.names``)."""

    robot: str  # robosuite robot name, e.g. "Panda"
    arm_joints: list[str]
    gripper_joints: list[str]
    ee_site: str  # the grip site, between the fingers
    hand_body: str  # the body the wrist force/torque sensor measures and grasped objects weld to
    left_pads: list[str]  # finger pad geoms
    right_pads: list[str]
    table_geom: str  # the table top's collision geom
    stage: str  # the name of the stage the world stands on (``muble.stage.table.STAGES``)
    objects: dict[int, str]  # scene id -> body name
    cameras: dict[str, str]  # role -> MuJoCo camera name
    init_qpos: np.ndarray  # the arm's rest configuration
    gripper_format: Any  # the robosuite gripper model


@dataclass
class TableTop:
    """The table top in the world frame: centre (x, y), half extents (hx, hy), top height and its body id (where a
    named part of it lies: ``muble.stage.table.part_box``)."""

    centre: np.ndarray
    half: np.ndarray
    top_z: float
    body: int


@runtime_checkable
class Environment(Protocol):
    """The operations primitives, sensors and renderers use. World frame = scene frame (metres, radians,
    quaternions w-first); object ids are scene ids."""

    model: "mujoco.MjModel"
    data: "mujoco.MjData"
    names: EnvironmentNames
    object_models: dict[int, "ObjectModel"]
    # Measured values per scene id, written by the measuring operations ({"weight": g, "stiffness": N/m,
    # "friction", "com_offset": [x, y] mm, "rattles": bool}).
    measurements: dict[int, dict[str, float]]
    # The run's motion planner for long moves, or None (primitives then take a registered one by name).
    planner: "MotionPlanner | None"
    # What plugins compute once per environment and keep (e.g. the gripper's measured pad geometry), by key.
    cache: dict[str, Any]
    gripper_command: float  # the last gripper command, -1 (open) .. 1 (closed)
    tare_force: np.ndarray | None
    gripper_actuator_ids: np.ndarray  # MuJoCo actuator ids of the fingers
    gripper_open_ctrl: np.ndarray  # their controls for the open and the closed hand
    gripper_closed_ctrl: np.ndarray

    @property
    def ee_site(self) -> str:
        """MuJoCo name of the grip site."""

    @property
    def arm_joint_names(self) -> list[str]: ...

    # ---- state
    @property
    def held_object(self) -> int | None:
        """Scene id of the object welded to the hand, or None."""

    @property
    def object_ids(self) -> list[int]:
        """Scene ids of the scene's objects."""

    def arm_q(self) -> np.ndarray: ...

    def arm_qd(self) -> np.ndarray: ...

    def ee_pose(self) -> Pose:
        """Pose of the grip site."""

    def object_pose(self, obj_id: int) -> Pose: ...

    def gripper_opening(self) -> float:
        """Distance between the finger pads (m)."""

    def wrist_wrench(self) -> tuple[np.ndarray, np.ndarray]:
        """Force (N) and torque (N·m) the arm exerts on the hand, world frame."""

    # ---- the world acting on its own (disturbances)
    control_listeners: list[Callable[[Any], None]]  # each called with the environment after every control step

    def apply_force(self, obj_id: int, force: np.ndarray, point: np.ndarray | None = None,
                    torque: np.ndarray | None = None) -> None:
        """Apply ``force`` (N, world frame) to the object at ``point`` (world; default its centre of mass), and a
        ``torque`` (N·m) beside it, from the next physics step on, until replaced (zero ends them); the physics
        integrates them."""

    # ---- geometry of what is there now
    def table(self) -> TableTop: ...

    def object_top(self, obj_id: int) -> float:
        """World z of the object's highest point, from its collision geometry as it stands now."""

    def object_bbox(self, obj_id: int) -> dict[str, float]:
        """Extents {"x", "y", "z"} (m) of the object's world-axis-aligned bounding box."""

    def touches_support(self, obj_id: int, tolerance: float = 0.001) -> bool:
        """The object touches the table or another object (live contacts within ``tolerance`` m)."""

    def is_lifted(self, obj_id: int) -> bool:
        """Held, clear of every support and above where it was grasped: what weighing needs."""

    def is_raised(self, obj_id: int) -> bool:
        """More than ``RAISED_HEIGHT`` above where the scene put it."""

    def top_down(self, yaw: float = 0.0) -> np.ndarray:
        """The grip-site orientation (quaternion) that points the hand straight down, turned by ``yaw`` (rad)
        about the vertical from the robot's rest pose: the frame of a top-down grasp."""

    # ---- planning
    def collision_world(self) -> "CollisionWorld":
        """The environment's collision world (a model copy, built once), synced with the current state: the held
        object moves with the hand and no contact is excused. Planning in it never touches the live physics."""

    # ---- acting
    def follow(self, trajectory: Trajectory, rate: float | None = None, settle: float = 0.0,
               stop: Callable[[Any], bool] | None = None) -> Any:
        """Track a joint trajectory of the arm (``stop(env)`` ends it early); returns how it went
        (``final_error`` rad, ``duration`` s, ``stopped_early``). Raises ``PhysicsError`` on a fault."""

    def advance(self, duration: float, on_control: Callable[[int], None] | None = None) -> None:
        """Run the physics for ``duration`` s at the current set-points."""

    def hold(self, duration: float) -> None:
        """Keep the arm still for ``duration`` s of simulated time."""

    def set_arm_target(self, q: np.ndarray, qd: np.ndarray | None = None, data: "mujoco.MjData | None" = None) -> None:
        """Set the arm servos' set-points (joint positions, optional velocity feed-forward) in ``data``: the live
        simulation's by default, or a copy's (to try a motion without touching the live physics)."""

    def set_gripper(self, command: float) -> None: ...

    def open_gripper(self) -> None: ...

    def close_gripper(self) -> None: ...

    # ---- measuring (the values land in ``measurements`` too)
    def tare(self) -> np.ndarray:
        """Remember the current wrist force as the zero for weighing."""

    def weigh(self, record: bool = True) -> float:
        """Weight in grams of the object in the hand, from the wrist force sensor; recorded in ``measurements``
        unless ``record`` is false."""

    def squeeze(self) -> float:
        """Stiffness (N/m) of the object between the fingers, from force against finger displacement."""

    def push(self, strokes: Any, steady: tuple[float, float], weight_g: float | None = None) -> Any:
        """Push the held object, standing on the table, along it: ``strokes`` are ``(trajectory, direction)``
        pairs (straight hand moves, their unit horizontal directions), ``steady`` the travel (m) within each
        stroke over which the wrist force is read; its weight ``weight_g``, by default the measured one. Returns a
        reading with ``friction`` (the coefficient, NaN without a steady stretch), ``normal`` (N) and ``samples``."""

    def balance(self, tilts: Any = ()) -> np.ndarray:
        """Horizontal offset (m, (2,), object frame) of the lifted object's centre of mass from its origin, from
        the wrist torque held still where it is and after each of ``tilts`` (trajectories tilting the hand in
        place: an object held leaning needs a second reading)."""

    def shake(self, ends: tuple[np.ndarray, np.ndarray], period: float, cycles: int) -> Any:
        """Shake the lifted object: ``cycles`` swings of ``period`` s between the arm configurations ``ends``;
        returns a reading with ``rattles`` (loose contents inside) and ``peak`` (N, the wrist force its rigid
        motion does not explain)."""

    # ---- snapshots and the scene graph
    def snapshot(self) -> Any: ...

    def restore(self, snap: Any) -> None:
        """Return to ``snap`` (from ``snapshot()``) exactly, e.g. after a failed attempt."""

    def sync_scene_graph(self) -> "SceneGraph":
        """The scene graph read back from the simulation now (ground truth)."""
