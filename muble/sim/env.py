"""The tabletop environment: reset from a scene, Gymnasium-style ``step``, fast trajectory ``follow``, grasp,
wrist force/torque, snapshots and scene-graph sync. See docs/environment.md for the API."""
from __future__ import annotations

import copy
import logging
import warnings
from dataclasses import dataclass
from typing import Any, Callable, Iterator

import mujoco
import numpy as np

from muble.core.errors import ConfigError, MubleDeprecationWarning, PhysicsError, unknown_name
from muble.core.environment import GRAVITY, ROBOT_DEFAULTS, TableTop
from muble.core.interfaces import MotionPlanner, Sensor
from muble.core.object_physics import CONTENTS_COLLISION_CLASS
from muble.core.objects import ObjectModel
from muble.core.scene import SceneGraph
from muble.core.types import Outcome, Pose, Trajectory
from muble.sim import sync
from muble.sim.collision_world import MujocoCollisionWorld
from muble.sim.control import OSC_OUTPUT_MAX, ArmServos, OperationalSpace, gripper_endpoints
from muble.sim.faults import FaultDetector
from muble.sim.grasp import GRASP_MODES, GraspModel
from muble.sim.sensor_noise import WristNoise, wrist_sensor_noise
from muble.sim.spaces import control_space
from muble.sim.world import build_world
from muble.stage.table import STAGES

logger = logging.getLogger(__name__)

# ``IK_JOINT_SERVO``: an end-effector delta pose is solved to a joint set-point (inverse kinematics through the
# dynamically consistent Jacobian inverse) and the joint servos track it; robosuite's delta-pose action.
CONTROLLERS = ("IK_JOINT_SERVO",)
# Other names accepted in configs, mapped to the controller they name: ``OSC_POSE`` (after robosuite's action of
# that name, though no operational-space torque law runs).
CONTROLLER_ALIASES = {"OSC_POSE": "IK_JOINT_SERVO"}


@dataclass
class Snapshot:
    """Everything needed to put the simulation back exactly: MuJoCo state, weld poses, controller state."""

    state: np.ndarray
    eq_data: np.ndarray
    held: int | None
    gripper_command: float
    tare: np.ndarray | None
    steps: int
    geom_solref: np.ndarray | None = None  # contact parameters the jaw contact law sets at run time
    grasp_height: float | None = None
    wrist_zero: np.ndarray | None = None  # a noisy wrist sensor's offset read at the tare (TabletopEnv.wrist_zero)


@dataclass
class FollowResult:
    """How a trajectory was tracked: final joint error (rad, max over joints) and simulated time (s)."""

    final_error: float
    duration: float
    stopped_early: bool = False


HOME_HEIGHT = 0.40  # m above the table top for the hand at rest: clear of the tallest object (~0.3 m)


def home_configuration(model: mujoco.MjModel, names: Any, height: float = HOME_HEIGHT) -> np.ndarray:
    """The robot's rest configuration raised (same hand orientation and x, y) until the hand is ``height`` above
    the table: robosuite's rest poses hold the hand 0.1-0.2 m above it, inside the taller objects' space."""
    from muble.sim.ik import ArmKinematics

    q0 = np.asarray(names.init_qpos, dtype=float)
    kinematics = ArmKinematics(model, mujoco.MjData(model), list(names.arm_joints), names.ee_site)
    pos, quat = kinematics.site_pose(q0)
    if pos[2] >= height:
        return q0
    result = kinematics.solve(np.array([pos[0], pos[1], height]), quat, q0, max_iterations=300)
    if not result.within(0.005, 0.02):
        logger.warning("no raised rest pose for %s (error %.3f m); keeping robosuite's", names.robot,
                       result.position_error)
        return q0
    return result.q


class TabletopEnv:
    """A robosuite tabletop with one arm, built from a scene graph and one ``ObjectModel`` per scene object; the
    implementation of ``muble.core.environment.Environment``, the interface plugins use.

    ``robot`` is a ``muble.app.config.RobotConfig`` (or anything with the same attributes); keyword overrides
    replace its fields (``TabletopEnv(scene, models, name="Sawyer", grasp="friction")``). ``stage=NAME`` builds
    the scene on another stage than the one its file names.

    ``noise`` gives the wrist force/torque sensor's error (``muble.sim.sensor_noise.WristNoise``, a mapping of its
    fields, or None: a perfect sensor), drawn from the stream of ``noise_stream`` (the run's seed, the episode's
    key).
    """

    def __init__(self, scene: SceneGraph, models: dict[int, ObjectModel], robot: Any = None,
                 sensors: dict[str, Sensor] | None = None, *, visual: bool = True, noise: Any = None,
                 noise_stream: tuple[int, int] = (0, 0), **overrides: Any):
        cfg = _robot_settings(robot, overrides)
        cfg["controller"] = CONTROLLER_ALIASES.get(cfg["controller"], cfg["controller"])
        if cfg["controller"] not in CONTROLLERS:
            raise ConfigError(unknown_name("controller", cfg["controller"], CONTROLLERS))
        if cfg["grasp"] not in GRASP_MODES:
            raise ConfigError(unknown_name("grasp mode", cfg["grasp"], GRASP_MODES))
        substeps = 1.0 / (cfg["control_freq"] * cfg["timestep"])
        if substeps < 1 or abs(substeps - round(substeps)) > 1e-6:
            raise ConfigError(f"control period 1/{cfg['control_freq']} s is not a whole number of "
                              f"{cfg['timestep']} s physics steps; change robot.control_freq or robot.timestep")
        self.config = cfg
        self.initial_scene = copy.deepcopy(scene)  # what reset() returns to
        self.scene = copy.deepcopy(scene)  # the latest sync_scene_graph()
        self.object_models = dict(models)
        # visual=False: a model for physics and planning alone (``build_world``), which no renderer can draw.
        self.model, self.names = build_world(scene, models, cfg["name"], cfg["gripper"], cfg["timestep"], visual,
                                              cfg["stage"])
        if cfg["name"] not in STAGES[self.names.stage].start_qpos:  # a stage's own rest pose is kept as it is
            self.names.init_qpos = home_configuration(self.model, self.names)
        self.data = mujoco.MjData(self.model)
        self.n_substeps = int(round(substeps))
        self.control_dt = self.n_substeps * self.model.opt.timestep

        n = self.names
        self.servos = ArmServos(self.model, self.data, n.arm_joints, n.arm_actuators, n.init_qpos)
        self.osc = OperationalSpace(self.model, self.servos, n.ee_site, n.init_qpos)
        self.gripper_actuator_ids = np.array([self.model.actuator(a).id for a in n.gripper_actuators])
        self.gripper_open_ctrl, self.gripper_closed_ctrl = gripper_endpoints(
            self.model, n.gripper_format, self.gripper_actuator_ids)
        self.gripper_qpos_adr = np.array([self.model.jnt_qposadr[self.model.joint(j).id] for j in n.gripper_joints])
        self.ee_site_id = self.model.site(n.ee_site).id
        self.force_adr = self.model.sensor_adr[self.model.sensor(n.force_sensor).id]
        self.torque_adr = self.model.sensor_adr[self.model.sensor(n.torque_sensor).id]
        self.ft_site_id = self.model.sensor(n.force_sensor).objid[0]
        self.grasp = GraspModel(self.model, n, cfg["grasp"])
        self.faults = FaultDetector(self.model, n)
        self.eq_data0 = self.model.eq_data.copy()
        self.sensors: dict[str, Sensor] = dict(sensors or {})
        # Only sensors that override on_step are called per control step (the physics loop stays cheap).
        self._stepping_sensors = [x for x in self.sensors.values() if type(x).on_step is not Sensor.on_step]
        self.control_listeners: list[Callable[["TabletopEnv"], None]] = []  # called after every control step

        self.action_space = control_space()
        self.gripper_command = -1.0
        self.tare_force: np.ndarray | None = None
        # The wrist sensor's stated figures (its datasheet, which the robot's software may know) and its error over
        # the episode; None for a perfect sensor, whose readings are MuJoCo's own.
        self.sensor_noise = WristNoise.of(noise)
        self._wrist_noise = wrist_sensor_noise(self.sensor_noise, *noise_stream)
        # A noisy sensor's offset (6,: force N, torque N·m, its own frame) as the tare read it with the empty hand
        # (the reading less the hand's modelled weight); None for a perfect sensor, which has none.
        self.wrist_zero: np.ndarray | None = None
        # Measured values per scene id ({"weight": g, "stiffness": N/m, "friction", "com_offset": [x, y] mm,
        # "rattles": bool}), filled by the measuring primitives' readings (muble_plugins.primitives.measure and
        # .handling for the built-in ones).
        self.measurements: dict[int, dict[str, float]] = {}
        self.planner: MotionPlanner | None = None  # the run's planner for long moves (the episode runner sets it)
        self.cache: dict[str, Any] = {}  # what plugins compute once per environment (Environment.cache)
        self._collision_world: MujocoCollisionWorld | None = None
        self.steps = 0
        self.broken: str | None = None
        self.reset()

    # ----------------------------------------------------------------------------------------------- episode
    def reset(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """Put every object back at its scene pose and the arm at rest, gripper open; returns (obs, info)."""
        mujoco.mj_resetData(self.model, self.data)
        self.scene = copy.deepcopy(self.initial_scene)
        self.model.eq_data[:] = self.eq_data0
        self.data.qpos[self.servos.qpos_adr] = self.names.init_qpos
        self.servos.command(self.data, self.names.init_qpos)
        self.grasp.held = None
        self.grasp.grasp_height = None
        self.grasp.jaws.reset()
        self.osc.goal_quat = None
        self.tare_force = None
        self.wrist_zero = None
        if self._wrist_noise is not None:
            self._wrist_noise.reset()
        self.measurements = {}
        self.steps = 0
        self.broken = None
        self.set_gripper(-1.0)
        init_fingers = getattr(self.names.gripper_format, "init_qpos", None)
        if init_fingers is not None and len(init_fingers) == len(self.gripper_qpos_adr):
            self.data.qpos[self.gripper_qpos_adr] = init_fingers
        mujoco.mj_forward(self.model, self.data)
        for sensor in self.sensors.values():
            sensor.reset(self)
        return self.observation(), {"outcome": None}

    def step(self, action: np.ndarray) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        """One control step of ``IK_JOINT_SERVO``: ``action`` = (dx, dy, dz, rx, ry, rz, gripper) in [-1, 1].

        The pose part is scaled to at most 5 cm / 0.5 rad per step (robosuite's defaults); gripper -1 opens,
        1 closes. A physics fault ends the episode: ``terminated`` is True and ``info["outcome"]`` is
        ``Outcome.BROKEN_SCENE`` with the reason in ``info["error"]``; call ``reset()`` afterwards.
        """
        action = np.asarray(action, dtype=float).reshape(-1)
        if action.shape != (7,):
            raise ConfigError(f"action must have 7 values (dx, dy, dz, rx, ry, rz, gripper), got {action.shape}")
        if self.broken:
            raise PhysicsError(f"the episode ended with a physics fault ({self.broken}); call reset() first")
        info: dict[str, Any] = {"outcome": None}
        try:
            if not np.isfinite(action).all():
                raise PhysicsError(f"action contains NaN or infinite values: {action.tolist()}")
            delta = np.minimum(np.maximum(action[:6], -1.0), 1.0)
            delta *= OSC_OUTPUT_MAX
            self.servos.command(self.data, self.osc.joint_target(self.data, delta))
            self.set_gripper(action[6])
            # One control period, as advance(control_dt) runs it, without its bookkeeping.
            mujoco.mj_step(self.model, self.data, nstep=self.n_substeps)
            self._after_control_step()
        except PhysicsError as e:
            self.broken = str(e)
            info.update(outcome=Outcome.BROKEN_SCENE, error=str(e))
            return {}, 0.0, True, False, info
        return self.observation(), 0.0, False, False, info

    # ------------------------------------------------------------------------------------------ physics loop
    def advance(self, duration: float, on_control: Callable[[int], None] | None = None,
                on_physics: Callable[[], None] | None = None) -> None:
        """Run the physics for ``duration`` seconds at the current set-points, ``n_substeps`` per ``mj_step``
        call; between calls, grasp and faults are checked and ``on_control(k)`` may set new set-points.

        ``on_physics()``, if given, is called after every physics step (the control period's ``n_substeps`` are
        then stepped one call each, which is the same computation): what a sensor sampled at the physics rate
        reads, ``data.sensordata`` as of that step."""
        count = max(1, int(round(duration / self.control_dt)))
        for k in range(count):
            if on_control is not None:
                on_control(k)
            if on_physics is None:
                mujoco.mj_step(self.model, self.data, nstep=self.n_substeps)
            else:
                for _ in range(self.n_substeps):
                    mujoco.mj_step(self.model, self.data)
                    on_physics()
            self._after_control_step()

    def _after_control_step(self) -> None:
        """Bookkeeping after every control step (``advance``, ``follow`` and ``step`` alike): faults, the grasp,
        and ``Sensor.on_step`` of the sensors that implement it."""
        self.steps += 1
        self.faults.check(self.data)
        self.grasp.update(self.data, closing=self.gripper_command > 0.0)
        for sensor in self._stepping_sensors:
            sensor.on_step(self)
        for listener in self.control_listeners:
            listener(self)

    def follow(self, trajectory: Trajectory, rate: float | None = None, settle: float = 0.0,
               stop: Callable[["TabletopEnv"], bool] | None = None) -> FollowResult:
        """Track a joint trajectory of the arm: set-points (position + velocity feed-forward) are sampled at
        ``rate`` Hz (default: the control rate) and held by the in-engine servos between samples.

        ``settle`` seconds at the final set-point follow. ``stop(env)`` is checked at each sample and ends
        tracking early when it returns True (e.g. contact reached). Raises ``PhysicsError`` on a fault.
        """
        if trajectory.q.shape[1] != len(self.servos.qpos_adr):
            raise ConfigError(f"trajectory has {trajectory.q.shape[1]} joints; the {self.names.robot} arm has "
                              f"{len(self.servos.qpos_adr)}: {self.names.arm_joints}")
        if not np.all(np.isfinite(trajectory.q)):
            raise PhysicsError("trajectory contains NaN or infinite joint values")
        rate = rate or 1.0 / self.control_dt
        nstep = max(1, int(round(1.0 / (rate * self.model.opt.timestep))))
        period = nstep * self.model.opt.timestep
        t = trajectory.t[0] + np.arange(int(np.ceil(trajectory.duration / period)) + 1) * period
        q_ref = np.stack([np.interp(t, trajectory.t, trajectory.q[:, j]) for j in range(trajectory.q.shape[1])], 1)
        qd_ref = np.gradient(q_ref, period, axis=0) if len(t) > 1 else np.zeros_like(q_ref)
        qd_ref[-1] = 0.0
        stopped = False
        start = self.data.time
        self.osc.goal_quat = None
        for i in range(len(t)):
            if stop is not None and stop(self):
                stopped = True
                break
            self.servos.command(self.data, q_ref[i], qd_ref[i])
            mujoco.mj_step(self.model, self.data, nstep=nstep)
            self._after_control_step()
        if not stopped:
            self.servos.command(self.data, q_ref[-1])
            if settle > 0:
                self.advance(settle)
        err = float(np.max(np.abs(self.servos.q(self.data) - q_ref[-1]))) if not stopped else float("nan")
        return FollowResult(err, float(self.data.time - start), stopped)

    def hold(self, duration: float) -> None:
        """Keep the arm at its current set-point for ``duration`` seconds of simulated time."""
        self.advance(duration)

    def set_arm_target(self, q: np.ndarray, qd: np.ndarray | None = None, data: mujoco.MjData | None = None) -> None:
        """Set the arm servos' set-points (joint positions, optional velocity feed-forward) in ``data``: the live
        simulation's by default, or a copy's."""
        self.servos.command(self.data if data is None else data, q, qd)

    # ---------------------------------------------------------------------------------------------- gripper
    def set_gripper(self, command: float) -> None:
        """Gripper command in [-1 (open), 1 (closed)], applied at the next physics step."""
        command = min(max(float(command), -1.0), 1.0)  # np.clip's result, without its per-call overhead
        self.gripper_command = command
        s = 0.5 * (command + 1.0)
        self.data.ctrl[self.gripper_actuator_ids] = (1 - s) * self.gripper_open_ctrl + s * self.gripper_closed_ctrl

    def open_gripper(self) -> None:
        self.set_gripper(-1.0)

    def close_gripper(self) -> None:
        self.set_gripper(1.0)

    @property
    def held_object(self) -> int | None:
        """Scene id of the object welded to the hand, or None."""
        return self.grasp.held

    # ------------------------------------------------------------------------------------------------ state
    @property
    def arm_joint_names(self) -> list[str]:
        return list(self.names.arm_joints)

    @property
    def arm_qpos_adr(self) -> np.ndarray:
        return self.servos.qpos_adr.copy()

    @property
    def arm_dof_adr(self) -> np.ndarray:
        return self.servos.dof_adr.copy()

    @property
    def joint_limits(self) -> np.ndarray:
        """(dof, 2) lower and upper limits of the arm joints."""
        return self.servos.limits.copy()

    @property
    def ee_site(self) -> str:
        return self.names.ee_site

    def arm_q(self) -> np.ndarray:
        return self.servos.q(self.data)

    def arm_qd(self) -> np.ndarray:
        return self.servos.qd(self.data)

    def ee_pose(self) -> Pose:
        """Pose of the grip site (between the fingers), world = scene frame."""
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, self.data.site_xmat[self.ee_site_id])
        return Pose(self.data.site_xpos[self.ee_site_id].copy(), quat)

    def gripper_opening(self) -> float:
        """Distance between the finger pads (m)."""
        pads = [self.model.geom(n).id for n in (self.names.left_pads[0], self.names.right_pads[0])]
        return float(np.linalg.norm(self.data.geom_xpos[pads[0]] - self.data.geom_xpos[pads[1]]))

    def object_pose(self, obj_id: int) -> Pose:
        b = self.grasp.body_of[obj_id]
        return Pose(self.data.xpos[b].copy(), self.data.xquat[b].copy())

    @property
    def object_ids(self) -> list[int]:
        """Scene ids of the scene's objects."""
        return sorted(self.names.objects)

    def table(self) -> TableTop:
        """The table top as the model has it (centre, half extents, top height, body id)."""
        g = self.model.geom(self.names.table_geom).id
        pos, size = self.data.geom_xpos[g], self.model.geom_size[g]
        return TableTop(pos[:2].copy(), size[:2].copy(), float(pos[2] + size[2]), int(self.model.geom_bodyid[g]))

    def object_top(self, obj_id: int) -> float:
        """World z of the object's highest point, from its collision geometry as it stands now."""
        m, d = self.model, self.data
        b = m.body(self.names.objects[obj_id]).id
        tops = []
        for g in np.flatnonzero(m.geom_bodyid == b):
            if m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0:
                continue
            if m.geom_contype[g] == CONTENTS_COLLISION_CLASS:
                continue  # the walls of a cavity inside it (loose contents)
            tops.append(d.geom_xpos[g][2] + m.geom_rbound[g])
            if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
                mesh = m.geom_dataid[g]
                start, n = m.mesh_vertadr[mesh], m.mesh_vertnum[mesh]
                verts = m.mesh_vert[start : start + n] @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g]
                tops[-1] = float(verts[:, 2].max())
        return float(max(tops)) if tops else float(d.xpos[b][2])

    def world_bbox(self, obj_id: int) -> dict[str, float]:
        """Extents {"x", "y", "z"} (m) of the object's world-axis-aligned bounding box, as it stands now."""
        return sync.world_bbox(self, obj_id)

    def object_bbox(self, obj_id: int) -> dict[str, float]:
        """Deprecated name of ``world_bbox``: the world-axis-aligned box, not the object-frame extents a scene
        object's ``bbox`` holds. Warns; goes with the next minor release."""
        warnings.warn("Environment.object_bbox() is deprecated: call Environment.world_bbox() (the same world-axis-"
                      "aligned box)", MubleDeprecationWarning, stacklevel=2)
        return self.world_bbox(obj_id)

    def touches_support(self, obj_id: int, tolerance: float = 0.001) -> bool:
        """The object touches the table or another object (live contacts within ``tolerance`` m)."""
        return sync.touches_support(self, obj_id, tolerance)

    def is_lifted(self, obj_id: int) -> bool:
        """Held, clear of every support and above where it was grasped: what weighing needs."""
        return sync.is_lifted(self, obj_id)

    def is_raised(self, obj_id: int) -> bool:
        """More than ``muble.sim.sync.RAISED_HEIGHT`` above where the scene put it."""
        return sync.is_raised(self, obj_id)

    def top_down(self, yaw: float = 0.0) -> np.ndarray:
        """The grip-site orientation pointing the hand straight down (the rest pose's, which points down for every
        supported arm), turned by ``yaw`` (rad) about the vertical: the frame of a top-down grasp."""
        rest = self.collision_world().ee_pose(self.names.init_qpos).quat
        turn = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
        out = np.empty(4)
        mujoco.mju_mulQuat(out, turn, rest)
        return out

    def collision_world(self) -> MujocoCollisionWorld:
        """This environment's collision world (a model copy, built on first use), synced with the current state:
        the held object moves with the hand and no contact is excused."""
        world = self._collision_world
        if world is None:
            world = self._collision_world = MujocoCollisionWorld(
                self.model, self.data, self.arm_joint_names, self.ee_site, "robot0_base", self.names.hand_body)
        world.hold(None)
        world.allow_contact([])
        world.sync(self.data)
        if self.held_object is not None:
            world.hold(self.names.objects[self.held_object])
        return world

    def apply_force(self, obj_id: int, force: np.ndarray, point: np.ndarray | None = None,
                    torque: np.ndarray | None = None) -> None:
        """Apply ``force`` (N, world frame) to the object at ``point`` (world; default its centre of mass), and a
        ``torque`` (N·m, world frame) beside it, from the next physics step on, until another call replaces them
        (zero ends them). The physics integrates them: nothing is moved directly, and ``snapshot``/``restore`` keep
        them with the state."""
        body = self.grasp.body_of[obj_id]
        self.data.xfrc_applied[body] = 0.0
        force = np.asarray(force, dtype=float)
        at = self.data.xipos[body] if point is None else np.asarray(point, dtype=float)
        # MuJoCo applies xfrc_applied at the body's centre of mass: a force elsewhere adds its moment about it.
        moment = np.cross(at - self.data.xipos[body], force)
        if torque is not None:
            moment = moment + np.asarray(torque, dtype=float)
        self.data.xfrc_applied[body, :3] = force
        self.data.xfrc_applied[body, 3:] = moment

    # ------------------------------------------------------------------------------------------------ sensing
    @property
    def pad_side(self) -> np.ndarray:
        """geom id -> 1 left pad, 2 right pad, 0 any other geom (read only)."""
        return self.grasp.pad_side

    def closing_axes(self) -> np.ndarray | None:
        """Unit vectors (2, 3) in which the left and the right pads close now (the jaw contact law's), or None."""
        axes = self.grasp.jaws.closing_axes(self.data)
        return None if axes is None else np.array([axes[1], axes[2]])

    def finger_contacts(self, obj_id: int) -> Iterator[tuple[int, Any, np.ndarray]]:
        """Each contact between ``obj_id`` and a finger's geom: (side 0 left / 1 right, the contact, the normal
        force with which the finger presses the object there, a world vector; the object pushes back with its
        opposite)."""
        model, data = self.model, self.data
        sides, geom_object = self.grasp.jaws.jaw_side, self.grasp.geom_object
        wrench = np.zeros(6)
        for i in range(data.ncon):
            c = data.contact[i]
            for finger, other, sign in ((c.geom1, c.geom2, 1.0), (c.geom2, c.geom1, -1.0)):
                side = sides[finger]
                if side and geom_object[other] == obj_id:
                    mujoco.mj_contactForce(model, data, i, wrench)
                    # contact frame row 0 is the normal, pointing from geom1 to geom2; force on geom2 is +normal
                    yield side - 1, c, sign * wrench[0] * c.frame[:3]

    def _hand_wrench(self) -> tuple[np.ndarray, np.ndarray]:
        """Force (N) and torque (N·m, about the wrist sensor's site) with which the arm holds up the hand's own
        weight, world frame: the hand body's subtree (fingers included, the held object not) from the robot's
        model."""
        model, data = self.model, self.data
        hand = model.body(self.names.hand_body).id
        weight = np.array([0.0, 0.0, float(model.body_subtreemass[hand]) * GRAVITY])
        lever = data.subtree_com[hand] - data.site_xpos[self.ft_site_id]
        return weight, np.cross(lever, weight)

    def load_wrench(self) -> tuple[np.ndarray, np.ndarray]:
        """The wrist force and torque (world frame, torque about the sensor's site) less the hand's own weight: what
        the held object (and anything it rests on or pushes) puts on the hand. Poses and sensor readings are those
        of the last physics step's start, so they belong together. A noisy sensor's offset as the last tare read it
        (``wrist_zero``, in the sensor's frame) is taken off too: its drift since that tare is what remains."""
        force, torque = self.wrist_wrench()
        hand_force, hand_torque = self._hand_wrench()
        zero = self.wrist_zero
        if zero is not None:
            rot = self.data.site_xmat[self.ft_site_id].reshape(3, 3)
            force, torque = force - rot @ zero[:3], torque - rot @ zero[3:]
        return force - hand_force, torque - hand_torque

    def wrist_wrench(self) -> tuple[np.ndarray, np.ndarray]:
        """Force (N) and torque (N·m) that the arm exerts on the hand, in the world frame, as the wrist sensor
        reads them (with its error, ``noise``, if it has one)."""
        rot = self.data.site_xmat[self.ft_site_id].reshape(3, 3)
        force = self.data.sensordata[self.force_adr:self.force_adr + 3]
        torque = self.data.sensordata[self.torque_adr:self.torque_adr + 3]
        if self._wrist_noise is not None:
            error = self._wrist_noise.error(self.data.time)  # in the sensor's frame, as its gauges err
            force, torque = force + error[:3], torque + error[3:]
        return rot @ force, rot @ torque

    def tare(self) -> np.ndarray:
        """Remember the current wrist force (hand alone, held still) as the zero for weighing; returns it. A noisy
        sensor's zero averages its output over ``muble.sim.sensor_noise.TARE_WINDOW``, and its offset is kept too
        (``wrist_zero``: the reading less the hand's modelled weight), which the other measurements take off."""
        if self._wrist_noise is None:
            self.tare_force = self.wrist_wrench()[0].copy()
        else:
            rot = self.data.site_xmat[self.ft_site_id].reshape(3, 3)
            error = self._wrist_noise.zero_error(self.data.time)
            force = rot @ (self.data.sensordata[self.force_adr:self.force_adr + 3] + error[:3])
            torque = rot @ (self.data.sensordata[self.torque_adr:self.torque_adr + 3] + error[3:])
            hand_force, hand_torque = self._hand_wrench()
            self.tare_force = force
            self.wrist_zero = np.concatenate([rot.T @ (force - hand_force), rot.T @ (torque - hand_torque)])
        return self.tare_force

    def snapshot(self) -> Snapshot:
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        state = np.empty(mujoco.mj_stateSize(self.model, spec))
        mujoco.mj_getState(self.model, self.data, state, spec)
        return Snapshot(state, self.model.eq_data.copy(), self.grasp.held, self.gripper_command,
                        None if self.tare_force is None else self.tare_force.copy(), self.steps,
                        self.model.geom_solref.copy(), self.grasp.grasp_height,
                        None if self.wrist_zero is None else self.wrist_zero.copy())

    def restore(self, snap: Snapshot) -> None:
        """Return to ``snap`` exactly (e.g. after a failed plan)."""
        mujoco.mj_setState(self.model, self.data, snap.state, mujoco.mjtState.mjSTATE_INTEGRATION)
        self.model.eq_data[:] = snap.eq_data
        if snap.geom_solref is not None:
            self.model.geom_solref[:] = snap.geom_solref
        self.grasp.held = snap.held
        self.grasp.grasp_height = snap.grasp_height
        self.osc.goal_quat = None
        self.gripper_command = snap.gripper_command
        self.tare_force = None if snap.tare is None else snap.tare.copy()
        self.wrist_zero = None if snap.wrist_zero is None else snap.wrist_zero.copy()
        self.steps = snap.steps
        self.broken = None
        mujoco.mj_forward(self.model, self.data)

    # ----------------------------------------------------------------------------------------- observation
    def observation(self) -> dict[str, Any]:
        """The built-in proprioception plus every sensor's reading under its name."""
        # Built directly rather than through ee_pose(): this runs after every step.
        ee_quat = np.empty(4)
        mujoco.mju_mat2Quat(ee_quat, self.data.site_xmat[self.ee_site_id])
        obs: dict[str, Any] = {
            "ee_pos": self.data.site_xpos[self.ee_site_id].copy(), "ee_quat": ee_quat,
            "joint_pos": self.arm_q(), "joint_vel": self.arm_qd(),
            "gripper_command": self.gripper_command, "held_object": self.grasp.held,
        }
        for name, sensor in self.sensors.items():
            obs[name] = sensor.read(self)
        return obs

    def sync_scene_graph(self) -> SceneGraph:
        from muble.sim.sync import scene_graph_from_sim

        self.scene = scene_graph_from_sim(self, self.scene)
        return self.scene

    def close(self) -> None:
        """Nothing to release (no GL context is opened here); kept for symmetry with renderers."""

    # ------------------------------------------------------------------------------------------------ deprecated
    def __getattr__(self, name: str) -> Any:
        """Deprecated: ``env.<primitive>(...)`` for a registered primitive that declares its ``reading`` (the
        built-in ``weigh``, ``squeeze``, ``push``, ``balance``, ``shake``) calls that reading on this environment,
        with a ``MubleDeprecationWarning`` that names it. The environment named these readings before they moved into
        the primitives; the forward goes with the next minor release."""
        if name.startswith("_"):
            raise AttributeError(name)
        from muble.plugins.registry import get_registry

        registry = get_registry()
        primitive = registry.get("primitive", name).record.factory if name in registry.names("primitive") else None
        reading = getattr(primitive, "reading", None)
        if reading is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        where = f"{reading.__module__}.{reading.__qualname__}"
        warnings.warn(f"Environment.{name}() is deprecated: the reading moved to the '{name}' primitive; call "
                      f"{where}(env, ...) instead", MubleDeprecationWarning, stacklevel=2)

        def forward(*args: Any, **kwargs: Any) -> Any:
            return reading(self, *args, **kwargs)

        return forward




def _robot_settings(robot: Any, overrides: dict[str, Any]) -> dict[str, Any]:
    fields = tuple(ROBOT_DEFAULTS)
    cfg = dict(ROBOT_DEFAULTS)
    if robot is not None:
        for f in fields:
            value = robot.get(f, cfg[f]) if isinstance(robot, dict) or hasattr(robot, "get") else getattr(robot, f, cfg[f])
            cfg[f] = value
    unknown = sorted(set(overrides) - set(fields))
    if unknown:
        raise ConfigError(f"unknown robot option(s) {unknown}; valid: {', '.join(fields)}")
    cfg.update(overrides)
    return cfg
