"""The environment as plugins see it: what a primitive, sensor or renderer may use, and nothing else.

``TabletopEnv`` (``muble.sim.env``) implements it; a primitive receives it in ``execute``/``feasible``, a sensor in
``read``/``reset``/``on_step``. Plugins depend on this protocol only, never on ``muble.sim`` modules. The MuJoCo
model and data are part of it on purpose: a primitive that plans its own motion reads geoms and contacts there.
See docs/plugins.md ("The environment API") for examples.

It names no primitive: a measuring primitive takes its reading itself, from the generic sensing members below (the
wrist wrench as the sensor reads it, with or without the hand's own weight; stepping with a callback per control
and per physics step; the held object, lifted and raised checks; the fingers' pads, closing directions and
contacts), as the built-in ones do (``muble_plugins.primitives.measure`` and ``.handling``).

The motion planner it holds (``planner``) and the collision world it plans in (``collision_world``) are defined here
too, so that this module imports nothing of ``muble.core.interfaces``, which lists ``MotionPlanner`` among the plugin
interfaces and re-exports both.
"""
from __future__ import annotations

import contextlib
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterator, Protocol, runtime_checkable

import numpy as np

from muble.core.types import JointGoal, Pose, PoseGoal, Trajectory

if TYPE_CHECKING:  # pragma: no cover
    from collections.abc import Iterable, Sequence

    import mujoco

    from muble.core.objects import ObjectModel
    from muble.core.scene import SceneGraph

# m/s², what the readings turn forces into weights with (and weights into forces), and the robot's model of its
# hand's weight too (``Environment.load_wrench``).
GRAVITY = 9.81
# The robot settings used where none are given, in one place: the defaults of the ``robot`` config schema
# (``muble.app.config.RobotConfig``, whose ``name`` the ``robot`` config group sets: Panda) and of an environment
# built with no robot config (``muble.sim.env``: the Gymnasium environments, tests); ``stage``: None builds each
# scene on the stage its file names (the generator's ``stage``), a name on that stage.
ROBOT_DEFAULTS: dict[str, Any] = {"name": "Panda", "gripper": None, "controller": "IK_JOINT_SERVO",
                                  "control_freq": 20.0, "timestep": 0.002, "grasp": "weld", "stage": None}


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


class CollisionWorld(ABC):
    """What a motion planner needs to know about the world: limits, validity, IK.

    The abstract methods are what every planner needs; the optional ones have defaults that planners can rely on
    (``last_contacts`` for messages, ``joint_names`` for trajectories, ``ee_pose`` and
    ``local_inverse_kinematics`` for Cartesian planners). ``hold``, ``allow_contact`` and ``contacts`` are what
    primitives use on the environment's collision world (``Environment.collision_world``).
    """

    # Body-name pairs in contact found by the last check that failed (for error messages); empty when unknown.
    last_contacts: "Sequence[tuple[str, str]]" = ()

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the planned joints, in the order of a configuration ``q``. Optional; default: none given."""
        return ()

    @property
    @abstractmethod
    def joint_limits(self) -> np.ndarray:
        """(dof, 2) array of lower and upper joint limits."""

    @abstractmethod
    def is_valid(self, q: np.ndarray) -> bool:
        """True when the arm at ``q`` (and anything it holds) collides with nothing."""

    @abstractmethod
    def inverse_kinematics(self, goal: PoseGoal, seeds: np.ndarray | None = None) -> np.ndarray:
        """A valid joint configuration reaching ``goal``; raises ``PlanningError`` if none exists."""

    def forward_kinematics(self, q: np.ndarray) -> np.ndarray:
        """End-effector position (3,) at ``q``. Optional (Cartesian planners use it)."""
        raise NotImplementedError(f"{type(self).__name__} does not provide forward kinematics")

    def ee_pose(self, q: np.ndarray) -> Pose:
        """End-effector pose at ``q``. Optional (Cartesian planners need it)."""
        raise NotImplementedError(f"{type(self).__name__} does not provide the end-effector pose")

    def local_inverse_kinematics(self, goal: PoseGoal, seed: np.ndarray) -> np.ndarray:
        """A valid configuration reaching ``goal`` on the branch of ``seed`` (small steps along a path). Optional;
        the default is ``inverse_kinematics`` seeded with ``seed`` alone."""
        return self.inverse_kinematics(goal, seeds=np.asarray(seed, dtype=float)[None])

    def contacts(self, q: np.ndarray) -> list[tuple[str, str]]:
        """Body-name pairs in contact at ``q``. Optional; the default reports none."""
        return []

    def hold(self, body: "str | int | None") -> None:
        """Carry ``body`` with the hand from now on (None: nothing). Optional for worlds nothing is grasped in."""
        raise NotImplementedError(f"{type(self).__name__} cannot carry an object with the hand")

    def allow_contact(self, bodies: "Iterable[str | int]", held_only: bool = False) -> None:
        """Contacts with ``bodies`` no longer make a configuration invalid (empty: none excused); with
        ``held_only``, only the held object's contacts with them are excused and the gripper's still count (an
        object set down into a bowl may touch it, the fingers round it may not). Optional."""
        raise NotImplementedError(f"{type(self).__name__} cannot excuse contacts")

    def resting_at(self, q: np.ndarray) -> "contextlib.AbstractContextManager[bool]":
        """A context manager for planning from ``q``: within it, contacts present at ``q`` between what the arm
        holds and objects it rests against (not the arm itself) count only where they get deeper, so such a
        start is valid and a path may leave the contact but not push into it; it yields whether ``q`` is valid
        then. Optional; the default tolerates nothing and yields ``is_valid(q)``."""
        return contextlib.nullcontext(self.is_valid(q))


class MotionPlanner(ABC):
    """Plans a collision-free joint-space trajectory; raises ``PlanningError`` with the reason when impossible."""

    @abstractmethod
    def plan(self, start_q: np.ndarray, goal: JointGoal | PoseGoal, world: CollisionWorld) -> Trajectory: ...

    def check(self, start_q: np.ndarray, goal: JointGoal | PoseGoal, world: CollisionWorld) -> None:
        """Raise ``PlanningError`` exactly where ``plan`` would, for callers that ask only whether the move exists
        (feasibility checks); a planner may skip what only shapes the trajectory. Default: ``plan``."""
        self.plan(start_q, goal, world)


@runtime_checkable
class Environment(Protocol):
    """The operations primitives, sensors and renderers use. World frame = scene frame (metres, radians,
    quaternions w-first); object ids are scene ids."""

    model: "mujoco.MjModel"
    data: "mujoco.MjData"
    names: EnvironmentNames
    object_models: dict[int, "ObjectModel"]
    # Measured values per scene id, written by the measuring primitives' readings, each under the property it
    # measures (the built-in ones: {"weight": g, "stiffness": N/m, "friction", "com_offset": [x, y] mm,
    # "rattles": bool}); the physical world's scene graph reads them from here.
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
    control_dt: float  # s of one control step: the physics steps between two calls of ``advance``'s ``on_control``

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
        """Force (N) and torque (N·m, about the sensor's site ``ft_site_id``) the arm exerts on the hand, world
        frame, as the wrist sensor reads them: with its error (``sensor_noise``) where it has one."""

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

    def world_bbox(self, obj_id: int) -> dict[str, float]:
        """Extents {"x", "y", "z"} (m) of the object's world-axis-aligned bounding box, as it stands now (a scene
        object's ``bbox`` is another thing: its extents in its own frame)."""

    def object_bbox(self, obj_id: int) -> dict[str, float]:
        """Deprecated name of ``world_bbox`` (it warns); goes with the next minor release."""

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

    def advance(self, duration: float, on_control: Callable[[int], None] | None = None,
                on_physics: Callable[[], None] | None = None) -> None:
        """Run the physics for ``duration`` s (whole control steps of ``control_dt``) at the current set-points;
        ``on_control(k)`` before the k-th control step may set new ones, and ``on_physics()`` after every physics
        step reads what a sensor sampled at the physics rate reads (``data`` as of that step)."""

    def hold(self, duration: float) -> None:
        """Keep the arm still for ``duration`` s of simulated time."""

    def set_arm_target(self, q: np.ndarray, qd: np.ndarray | None = None, data: "mujoco.MjData | None" = None) -> None:
        """Set the arm servos' set-points (joint positions, optional velocity feed-forward) in ``data``: the live
        simulation's by default, or a copy's (to try a motion without touching the live physics)."""

    def set_gripper(self, command: float) -> None: ...

    def open_gripper(self) -> None: ...

    def close_gripper(self) -> None: ...

    # ---- sensing: what a measuring primitive reads (it records its values in ``measurements``)
    ft_site_id: int  # MuJoCo id of the wrist force/torque sensor's site, which its torque is taken about
    # The wrist sensor's stated figures (``force_white_n``, ``force_drift_n_per_sqrt_s``, ``torque_white_nm``,
    # ``torque_drift_nm_per_sqrt_s``, ``sample_rate_hz``; all zero: a perfect sensor), as its datasheet gives them:
    # what a reading may allow for. The error itself is in every ``wrist_wrench``.
    sensor_noise: Any
    # geom id -> 1 for the left fingers' pad geoms (``names.left_pads``), 2 for the right's, 0 for any other geom
    pad_side: np.ndarray

    def tare(self) -> np.ndarray:
        """Remember the current wrist force (the empty hand, still) as the zero for weighing (``tare_force``);
        returns it. A noisy sensor's offset is kept too, which ``load_wrench`` takes off."""

    def load_wrench(self) -> tuple[np.ndarray, np.ndarray]:
        """``wrist_wrench`` less the hand's own weight (force N, torque N·m about ``ft_site_id``, world frame),
        from the robot's model of its hand with the fingers where they are now, and less the sensor's offset as
        the last ``tare`` read it: what the held object, and anything it rests on or pushes, puts on the hand."""

    def closing_axes(self) -> np.ndarray | None:
        """Unit vectors (2, 3), world frame, in which the left and the right pads close now: from each side's pad
        centre towards the other's (the jaw contact law's own directions); None where the centres coincide."""

    def finger_contacts(self, obj_id: int) -> Iterator[tuple[int, Any, np.ndarray]]:
        """Each live contact between the object and a geom of either finger (its pads and every colliding geom
        that moves with them): ``(side, contact, force)`` with side 0 left, 1 right, the MuJoCo contact
        (``pos``, ``dist``, ``frame``) and the normal force (N, world frame) with which the finger presses the
        object there; the object presses back with its opposite."""

    # ---- snapshots and the scene graph
    def snapshot(self) -> Any: ...

    def restore(self, snap: Any) -> None:
        """Return to ``snap`` (from ``snapshot()``) exactly, e.g. after a failed attempt."""

    def sync_scene_graph(self) -> "SceneGraph":
        """The scene graph read back from the simulation now (ground truth)."""
