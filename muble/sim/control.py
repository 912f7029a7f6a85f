"""Control at the control rate, physics at the physics rate.

The arm's torque motors are turned into MuJoCo joint servos (``gain·ctrl − kp·q − kv·q̇``), and the arm carries
MuJoCo gravity compensation, so the joint impedance runs inside ``mj_step`` at every substep, in C. Python only
computes a new joint set-point once per control period; the physics then advances ``k`` substeps in one
``mj_step(model, data, nstep=k)`` call. This is what keeps Python out of the physics loop.

The end-effector controller (``OSC_POSE``) is an operational-space law evaluated at the control rate: the task
error (position and rotation vector) is mapped to joint space through the dynamically consistent inverse of the
Jacobian, ``J̄ = M⁻¹Jᵀ(JM⁻¹Jᵀ + λI)⁻¹``, with a null-space pull towards the rest posture; the joint servos
realise that displacement.
"""
from __future__ import annotations

import mujoco
import numpy as np

# robosuite's OSC_POSE defaults: an action of 1 moves 5 cm or turns 0.5 rad in one control step.
OSC_OUTPUT_MAX = np.array([0.05, 0.05, 0.05, 0.5, 0.5, 0.5])
SERVO_STIFFNESS_PER_NM = 15.0  # kp (N·m/rad) per N·m of the joint's torque limit
SERVO_DAMPING_RATIO = 1.0
NULLSPACE_GAIN = 0.1
DLS_DAMPING = 1e-4


class ArmServos:
    """Joint position servos on the arm actuators, with velocity feed-forward folded into the set-point."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, joints: list[str], actuators: list[str],
                 rest_q: np.ndarray):
        self.model = model
        self.joint_ids = np.array([model.joint(j).id for j in joints])
        self.qpos_adr = model.jnt_qposadr[self.joint_ids].copy()
        self.dof_adr = model.jnt_dofadr[self.joint_ids].copy()
        self.actuator_ids = np.array([model.actuator(a).id for a in actuators])
        self.limits = model.jnt_range[self.joint_ids].copy()
        unlimited = model.jnt_limited[self.joint_ids] == 0
        self.limits[unlimited] = (-2 * np.pi, 2 * np.pi)
        torque = np.abs(model.actuator_ctrlrange[self.actuator_ids]).max(axis=1)
        self.kp = SERVO_STIFFNESS_PER_NM * torque
        # Damping from the joint-space inertia at the rest posture (critically damped per joint).
        data.qpos[self.qpos_adr] = rest_q
        mujoco.mj_forward(model, data)
        inertia = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, inertia)
        m_ii = inertia[self.dof_adr, self.dof_adr] + model.dof_armature[self.dof_adr]
        self.kv = 2.0 * SERVO_DAMPING_RATIO * np.sqrt(self.kp * m_ii)
        for i, a in enumerate(self.actuator_ids):
            model.actuator_gaintype[a] = mujoco.mjtGain.mjGAIN_FIXED
            model.actuator_gainprm[a, :] = 0.0
            model.actuator_gainprm[a, 0] = self.kp[i]
            model.actuator_biastype[a] = mujoco.mjtBias.mjBIAS_AFFINE
            model.actuator_biasprm[a, :] = 0.0
            model.actuator_biasprm[a, 1] = -self.kp[i]
            model.actuator_biasprm[a, 2] = -self.kv[i]
            # The former control range was the torque limit; it now bounds the servo force instead.
            model.actuator_forcerange[a] = (-torque[i], torque[i])
            model.actuator_forcelimited[a] = 1
            model.actuator_ctrlrange[a] = self.limits[i]
            model.actuator_ctrllimited[a] = 0

    def q(self, data: mujoco.MjData) -> np.ndarray:
        return data.qpos[self.qpos_adr].copy()

    def qd(self, data: mujoco.MjData) -> np.ndarray:
        return data.qvel[self.dof_adr].copy()

    def command(self, data: mujoco.MjData, q_target: np.ndarray, qd_target: np.ndarray | None = None) -> None:
        """Servo to ``q_target`` (clipped to the joint limits), tracking ``qd_target`` if given."""
        q_target = np.clip(q_target, self.limits[:, 0], self.limits[:, 1])
        if qd_target is not None:
            # kp(q* + kv/kp·q̇* − q) − kv·q̇ = kp(q* − q) + kv(q̇* − q̇): exact velocity feed-forward.
            q_target = q_target + self.kv / self.kp * qd_target
        data.ctrl[self.actuator_ids] = q_target


class OperationalSpace:
    """``OSC_POSE`` evaluated at the control rate: EE delta pose -> joint set-point.

    The goal pose is the current pose moved by the delta (robosuite's delta semantics). A few Newton steps of the
    dynamically consistent inverse on a scratch ``MjData`` make the set-point reach the goal exactly even for
    large deltas, where a single linear step would drift.
    """

    def __init__(self, model: mujoco.MjModel, servos: ArmServos, site: str, rest_q: np.ndarray, iterations: int = 3):
        self.model = model
        self.servos = servos
        self.site_id = model.site(site).id
        self.rest_q = np.asarray(rest_q, dtype=float)
        self.iterations = iterations
        # The goal orientation persists between steps so zero rotation deltas never let it drift; None = current.
        self.goal_quat: np.ndarray | None = None
        self.scratch = mujoco.MjData(model)
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))
        self._mass = np.zeros((model.nv, model.nv))

    def joint_target(self, data: mujoco.MjData, delta: np.ndarray) -> np.ndarray:
        """Joint set-point moving the EE by ``delta`` = (dx, dy, dz, rx, ry, rz) metres / radians, world frame."""
        model, scratch, dofs = self.model, self.scratch, self.servos.dof_adr
        goal_pos = data.site_xpos[self.site_id] + delta[:3]
        cur_quat = np.empty(4)
        mujoco.mju_mat2Quat(cur_quat, data.site_xmat[self.site_id])
        turn = np.empty(4)
        mujoco.mju_axisAngle2Quat(turn, delta[3:] / max(np.linalg.norm(delta[3:]), 1e-12), np.linalg.norm(delta[3:]))
        goal_quat = np.empty(4)
        mujoco.mju_mulQuat(goal_quat, turn, cur_quat if self.goal_quat is None else self.goal_quat)
        self.goal_quat = goal_quat
        # The inertia-weighted inverse uses the mass matrix at the current state.
        mujoco.mj_fullM(model, data, self._mass)
        m_inv = np.linalg.inv(self._mass[np.ix_(dofs, dofs)])
        scratch.qpos[:] = data.qpos
        q = data.qpos[self.servos.qpos_adr].copy()
        for it in range(self.iterations):
            mujoco.mj_kinematics(model, scratch)
            mujoco.mj_comPos(model, scratch)
            mujoco.mj_jacSite(model, scratch, self._jacp, self._jacr, self.site_id)
            jac = np.vstack([self._jacp[:, dofs], self._jacr[:, dofs]])
            quat = np.empty(4)
            mujoco.mju_mat2Quat(quat, scratch.site_xmat[self.site_id])
            err = np.empty(6)
            err[:3] = goal_pos - scratch.site_xpos[self.site_id]
            err[3:] = _rotation_error(goal_quat, quat)
            j_bar = m_inv @ jac.T @ np.linalg.inv(jac @ m_inv @ jac.T + DLS_DAMPING * np.eye(6))
            dq = j_bar @ err
            if it == 0:
                dq += (np.eye(len(dofs)) - j_bar @ jac) @ (NULLSPACE_GAIN * (self.rest_q - q))
            q = np.clip(q + dq, self.servos.limits[:, 0], self.servos.limits[:, 1])
            scratch.qpos[self.servos.qpos_adr] = q
        return q


def _rotation_error(target: np.ndarray, current: np.ndarray) -> np.ndarray:
    """Rotation vector (world frame) turning ``current`` into ``target`` (quaternions w, x, y, z)."""
    conj = np.empty(4)
    mujoco.mju_negQuat(conj, current)
    diff = np.empty(4)
    mujoco.mju_mulQuat(diff, target, conj)
    if diff[0] < 0:
        diff = -diff
    vel = np.empty(3)
    mujoco.mju_quat2Vel(vel, diff, 1.0)
    return vel


def gripper_endpoints(model: mujoco.MjModel, gripper_model, actuator_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Actuator controls of the fully open and fully closed gripper, from robosuite's gripper action mapping.

    Some robosuite grippers integrate their action over calls (a speed limit); driving the mapping to its end
    stops gives the stateless end points, and a command in [-1, 1] is then interpolated between them.
    """
    ctrl_range = model.actuator_ctrlrange[actuator_ids]
    bias = 0.5 * (ctrl_range[:, 1] + ctrl_range[:, 0])
    weight = 0.5 * (ctrl_range[:, 1] - ctrl_range[:, 0])
    ends = []
    for command in (-1.0, 1.0):
        action = None
        for _ in range(1000):
            action = np.asarray(gripper_model.format_action(np.array([command])), dtype=float)
        ends.append(bias + weight * np.clip(action, -1.0, 1.0))
    return ends[0], ends[1]
