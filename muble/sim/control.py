"""Control at the control rate, physics at the physics rate.

The arm's torque motors are turned into MuJoCo joint servos (``gain·ctrl − kp·q − kv·q̇``), and the arm carries
MuJoCo gravity compensation, so the joint impedance runs inside ``mj_step`` at every substep, in C. Python only
computes a new joint set-point once per control period; the physics then advances ``k`` substeps in one
``mj_step(model, data, nstep=k)`` call. This is what keeps Python out of the physics loop.

The end-effector controller (``IK_JOINT_SERVO``; ``OSC_POSE`` in configs names it too) is inverse kinematics evaluated at the
control rate, not an operational-space torque law: the task error (position and rotation vector) is mapped to joint
space through the dynamically consistent inverse of the Jacobian, ``J̄ = M⁻¹Jᵀ(JM⁻¹Jᵀ + λI)⁻¹``, with a null-space
pull towards the rest posture; the joint servos realise that displacement.
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


def index_or_slice(index: np.ndarray) -> np.ndarray | slice:
    """``index`` as a slice when it is a run of consecutive integers (a view, no gather), else unchanged."""
    n = len(index)
    if n and np.array_equal(index, np.arange(index[0], index[0] + n)):
        return slice(int(index[0]), int(index[0]) + n)
    return index


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
        self._lower = np.ascontiguousarray(self.limits[:, 0])
        self._upper = np.ascontiguousarray(self.limits[:, 1])
        self._feed_forward = self.kv / self.kp
        # Slices where the addresses are consecutive (every supported arm): views instead of gathers.
        self._ctrl = index_or_slice(self.actuator_ids)
        self._qpos = index_or_slice(self.qpos_adr)
        self._qvel = index_or_slice(self.dof_adr)

    def q(self, data: mujoco.MjData) -> np.ndarray:
        return data.qpos[self._qpos].copy()

    def qd(self, data: mujoco.MjData) -> np.ndarray:
        return data.qvel[self._qvel].copy()

    def command(self, data: mujoco.MjData, q_target: np.ndarray, qd_target: np.ndarray | None = None) -> None:
        """Servo to ``q_target`` (clipped to the joint limits), tracking ``qd_target`` if given."""
        # Called once per control step: ufuncs on cached bounds are several times cheaper than np.clip.
        target = np.maximum(q_target, self._lower)
        np.minimum(target, self._upper, out=target)
        if qd_target is not None:
            # kp(q* + kv/kp·q̇* − q) − kv·q̇ = kp(q* − q) + kv(q̇* − q̇): exact velocity feed-forward.
            target += self._feed_forward * qd_target
        data.ctrl[self._ctrl] = target


class OperationalSpace:
    """``IK_JOINT_SERVO`` evaluated at the control rate: EE delta pose -> joint set-point.

    The goal pose is the current pose moved by the delta (robosuite's delta semantics). A few Newton steps of the
    dynamically consistent inverse on a scratch ``MjData`` make the set-point reach the goal exactly even for
    large deltas, where a single linear step would drift.

    This runs once per control step of ``TabletopEnv.step``, so it is written to keep Python small: every array is
    allocated here once, the arm's block of the mass matrix is gathered straight from MuJoCo's sparse ``qM`` (no
    nv x nv expansion over every object's free joint), the Jacobian block is a view when the arm's degrees of
    freedom are contiguous (they are for every supported robot), and the inverses use MuJoCo's Cholesky routines
    (one C call each) instead of LAPACK.
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
        nv, dofs = model.nv, servos.dof_adr
        n = len(dofs)
        self._mass = np.zeros((nv, nv))
        self._jac_full = np.zeros((6, nv))  # rows 0-2 translational, 3-5 rotational Jacobian of the site
        self._arm_mass = np.zeros((n, n))
        block = index_or_slice(dofs)
        if isinstance(block, slice):
            self._arm_jac = self._jac_full[:, block]  # a view: refreshed by mj_jacSite in place
            self._jac_index = None
        else:
            self._arm_jac = np.zeros((6, n))
            self._jac_index = dofs
        self._mass_index = np.ix_(dofs, dofs)
        self._jacp = self._jac_full[:3]
        self._jacr = self._jac_full[3:]
        self._q = np.zeros(n)
        self._pull = np.zeros(n)
        self._err = np.zeros(6)
        self._rhs = np.zeros(6)
        self._lam = np.zeros((6, 6))
        self._cur_quat = np.zeros(4)
        self._quat = np.zeros(4)
        self._turn = np.zeros(4)
        self._conj = np.zeros(4)
        self._diff = np.zeros(4)
        self._axis = np.zeros(3)
        self._lower = np.ascontiguousarray(servos.limits[:, 0])
        self._upper = np.ascontiguousarray(servos.limits[:, 1])
        self._qpos_block = index_or_slice(servos.qpos_adr)
        self._damping = DLS_DAMPING * np.eye(6)
        self._chol = np.zeros((n, n))
        self._m_inv = np.zeros((n, n))
        self._unit = np.eye(n)
        self._qm_index = self._arm_qm_index(dofs)

    def _arm_qm_index(self, dofs: np.ndarray) -> np.ndarray | None:
        """Where each entry of the arm's mass block lies in MuJoCo's sparse ``qM``, or None (then ``mj_fullM``).

        Found by expanding a ``qM`` that holds its own positions; gathering those entries makes the per-step
        cost independent of how many objects (free joints) the scene has, where ``mj_fullM`` fills nv x nv.
        """
        model = self.model
        probe = mujoco.MjData(model)
        sparse = _sparse_mass(probe)
        if sparse is None:
            return None
        sparse[:] = np.arange(1, sparse.size + 1)
        mujoco.mj_fullM(model, probe, self._mass)
        index = np.rint(self._mass[self._mass_index]).astype(int) - 1
        if (index < 0).any():  # a structural zero inside the block (not a serial arm)
            return None
        # Check against the dense expansion on a real mass matrix before trusting it.
        mujoco.mj_forward(model, probe)
        mujoco.mj_fullM(model, probe, self._mass)
        if not np.array_equal(_sparse_mass(probe)[index], self._mass[self._mass_index]):
            return None
        return index

    def _refresh_mass(self, data: mujoco.MjData) -> None:
        if self._qm_index is not None:
            np.take(_sparse_mass(data), self._qm_index, out=self._arm_mass)
        else:
            mujoco.mj_fullM(self.model, data, self._mass)
            self._arm_mass[:] = self._mass[self._mass_index]

    def _arm_mass_inverse(self) -> np.ndarray:
        """Inverse of the arm's mass block by Cholesky, column by column (MuJoCo's C routines: no LAPACK call,
        whose fixed cost and thread start-up dwarf a 7x7 inverse)."""
        chol, m_inv = self._chol, self._m_inv
        chol[:] = self._arm_mass
        mujoco.mju_cholFactor(chol, 0.0)
        for i, unit in enumerate(self._unit):
            mujoco.mju_cholSolve(m_inv[i], chol, unit)  # row i = column i: the inverse is symmetric
        return m_inv

    def _refresh_jacobian(self, scratch: mujoco.MjData) -> None:
        mujoco.mj_jacSite(self.model, scratch, self._jacp, self._jacr, self.site_id)
        if self._jac_index is not None:
            np.take(self._jac_full, self._jac_index, axis=1, out=self._arm_jac)

    def joint_target(self, data: mujoco.MjData, delta: np.ndarray) -> np.ndarray:
        """Joint set-point moving the EE by ``delta`` = (dx, dy, dz, rx, ry, rz) metres / radians, world frame."""
        model, scratch, site = self.model, self.scratch, self.site_id
        goal_pos = data.site_xpos[site] + delta[:3]
        previous = self.goal_quat
        if previous is None:
            mujoco.mju_mat2Quat(self._cur_quat, data.site_xmat[site])
            previous = self._cur_quat
        angle = float(np.sqrt(delta[3] * delta[3] + delta[4] * delta[4] + delta[5] * delta[5]))
        np.divide(delta[3:], max(angle, 1e-12), out=self._axis)
        mujoco.mju_axisAngle2Quat(self._turn, self._axis, angle)
        goal_quat = np.empty(4)  # a new array: callers may keep the previous goal
        mujoco.mju_mulQuat(goal_quat, self._turn, previous)
        self.goal_quat = goal_quat
        # The inertia-weighted inverse uses the arm's block of the mass matrix at the current state.
        self._refresh_mass(data)
        m_inv = self._arm_mass_inverse()
        scratch.qpos[:] = data.qpos
        q = self._q
        q[:] = data.qpos[self._qpos_block]
        jac, err, lam, rhs = self._arm_jac, self._err, self._lam, self._rhs
        for it in range(self.iterations):
            mujoco.mj_kinematics(model, scratch)
            mujoco.mj_comPos(model, scratch)
            self._refresh_jacobian(scratch)
            mujoco.mju_mat2Quat(self._quat, scratch.site_xmat[site])
            np.subtract(goal_pos, scratch.site_xpos[site], out=err[:3])
            self._rotation_error(goal_quat, self._quat, err[3:])
            # J̄ = M⁻¹Jᵀ(JM⁻¹Jᵀ+λI)⁻¹;  dq = J̄·err, plus on the first step the null-space pull
            # (I − J̄J)·p = p + J̄·(−J·p), so both share one solve with the right-hand side err − J·p.
            m_inv_jt = m_inv @ jac.T
            np.add(jac @ m_inv_jt, self._damping, out=lam)
            mujoco.mju_cholFactor(lam, 0.0)
            if it == 0:
                np.subtract(self.rest_q, q, out=self._pull)
                self._pull *= NULLSPACE_GAIN
                np.subtract(err, jac @ self._pull, out=rhs)
                mujoco.mju_cholSolve(rhs, lam, rhs)
                q += m_inv_jt @ rhs
                q += self._pull
            else:
                mujoco.mju_cholSolve(rhs, lam, err)
                q += m_inv_jt @ rhs
            np.maximum(q, self._lower, out=q)
            np.minimum(q, self._upper, out=q)
            scratch.qpos[self._qpos_block] = q
        return q.copy()

    def _rotation_error(self, target: np.ndarray, current: np.ndarray, out: np.ndarray) -> None:
        """Rotation vector (world frame) turning ``current`` into ``target``, into ``out``."""
        mujoco.mju_negQuat(self._conj, current)
        mujoco.mju_mulQuat(self._diff, target, self._conj)
        if self._diff[0] < 0:
            np.negative(self._diff, out=self._diff)
        mujoco.mju_quat2Vel(out, self._diff, 1.0)


def _sparse_mass(data: mujoco.MjData) -> np.ndarray | None:
    """The sparse mass matrix that ``mj_fullM`` expands: ``qM`` up to MuJoCo 3.3, ``M`` after it was removed."""
    sparse = getattr(data, "qM", None)
    return getattr(data, "M", None) if sparse is None else sparse


def gripper_endpoints(model: mujoco.MjModel, gripper_model, actuator_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Actuator controls of the fully open and fully closed gripper, from robosuite's gripper action mapping.

    Some robosuite grippers integrate their action over calls (a speed limit); driving the mapping to its end
    stops gives the stateless end points, and a command in [-1, 1] is then interpolated between them.
    """
    ctrl_range = model.actuator_ctrlrange[actuator_ids]
    # A function of the gripper's class and control range: driven once per process for each (a fresh gripper
    # model, as every world builds, starts from the same internal state).
    kind = (type(gripper_model).__module__, type(gripper_model).__qualname__, ctrl_range.tobytes())
    cached = _endpoints_by_kind.get(kind)
    if cached is None:
        bias = 0.5 * (ctrl_range[:, 1] + ctrl_range[:, 0])
        weight = 0.5 * (ctrl_range[:, 1] - ctrl_range[:, 0])
        ends = []
        for command in (-1.0, 1.0):
            action = None
            for _ in range(1000):
                action = np.asarray(gripper_model.format_action(np.array([command])), dtype=float)
            ends.append(bias + weight * np.clip(action, -1.0, 1.0))
        cached = _endpoints_by_kind[kind] = (ends[0], ends[1])
    return cached[0].copy(), cached[1].copy()


_endpoints_by_kind: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
