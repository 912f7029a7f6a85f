"""Inverse kinematics for a MuJoCo arm: damped least squares on MuJoCo Jacobians, several seeds, joint limits.

The solver works on its own ``MjData`` so the live simulation state is never touched. Only the arm's joints
move; everything else in ``data`` (gripper fingers, objects) stays where it is.
"""
from __future__ import annotations

import contextlib
import logging
import math
from dataclasses import dataclass

import mujoco
import numpy as np

logger = logging.getLogger(__name__)

LIMIT_MARGIN = 0.01  # rad kept between an IK solution and each joint limit


def _checked_solve():
    """(solve, errors): np.linalg.solve's own kernel without its argument checks (a third of the IK loop's time)
    and the error state under which it raises np.linalg.solve's ``LinAlgError``, entered once around a loop of
    solves (entering it costs as much as a solve), where this numpy has the kernel and it gives np.linalg.solve's
    numbers and errors on a probe; np.linalg.solve itself otherwise (the kernel is numpy's private layout, which a
    numpy release may change)."""
    try:
        from numpy.linalg import _umath_linalg
        from numpy.linalg._linalg import _raise_linalgerror_singular

        def errors():
            return np.errstate(call=_raise_linalgerror_singular, invalid="call", over="ignore", divide="ignore",
                               under="ignore")

        def fast(a: np.ndarray, b: np.ndarray) -> np.ndarray:
            return _umath_linalg.solve1(a, b, signature="dd->d")

        a = np.array([[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 2.0]])
        b = np.array([1.0, -2.0, 0.5])
        with errors():
            if not np.array_equal(fast(a, b), np.linalg.solve(a, b)):
                return np.linalg.solve, contextlib.nullcontext
            try:
                fast(np.zeros((3, 3)), b)
            except np.linalg.LinAlgError:
                return fast, errors
        return np.linalg.solve, contextlib.nullcontext
    except Exception:  # another numpy layout or signature
        return np.linalg.solve, contextlib.nullcontext


_solve, _solve_errors = _checked_solve()


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """``index`` as a slice when its entries are consecutive (the same elements), else itself."""
    if len(index) and np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        return slice(int(index[0]), int(index[0]) + len(index))
    return index


def quat_error(target: np.ndarray, current: np.ndarray) -> np.ndarray:
    """Rotation vector (world frame, radians) that turns ``current`` into ``target`` (both w, x, y, z)."""
    conj = np.empty(4)
    mujoco.mju_negQuat(conj, current)
    diff = np.empty(4)
    mujoco.mju_mulQuat(diff, target, conj)
    if diff[0] < 0.0:  # the shorter way round
        diff = -diff
    err = np.empty(3)
    mujoco.mju_quat2Vel(err, diff, 1.0)
    return err


@dataclass
class IKResult:
    q: np.ndarray
    position_error: float
    orientation_error: float
    iterations: int

    def within(self, position_tolerance: float, orientation_tolerance: float) -> bool:
        return self.position_error <= position_tolerance and self.orientation_error <= orientation_tolerance


class ArmKinematics:
    """Forward and inverse kinematics of the joints ``joint_names`` to the site ``site_name``.

    ``data`` is a scratch ``MjData`` of ``model`` owned by the caller; every call overwrites the arm's qpos in it.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, joint_names: list[str], site_name: str):
        self.model = model
        self.data = data
        self.joint_names = tuple(joint_names)
        joints = [model.joint(n) for n in joint_names]
        for j in joints:
            if int(model.jnt_type[j.id]) not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
                raise ValueError(f"joint '{j.name}' is not a hinge or slide joint; IK handles 1-DoF arm joints")
        self.qpos_adr = np.array([model.jnt_qposadr[j.id] for j in joints])
        self.dof_adr = np.array([model.jnt_dofadr[j.id] for j in joints])
        self.site_id = model.site(site_name).id
        limited = np.array([model.jnt_limited[j.id] for j in joints], dtype=bool)
        ranges = np.array([model.jnt_range[j.id] for j in joints], dtype=float)
        # Unlimited joints get one turn either way: enough for any pose, bounded for sampling.
        ranges[~limited] = (-np.pi, np.pi)
        self.limits = ranges
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))
        # Slices where the joints' addresses are consecutive (every supported arm): the same elements as the
        # address arrays, read and written without numpy's fancy indexing.
        self._qpos_index = _as_slice(self.qpos_adr)
        self._dof_index = _as_slice(self.dof_adr)
        self._quat, self._conj, self._diff = np.empty(4), np.empty(4), np.empty(4)
        self._bounds: tuple = (None,)  # (limits, lowest, highest) a solution may take within them
        self._damped: dict[tuple[float, int], np.ndarray] = {}  # damping * identity, by (damping, rows)
        self._buffers: dict[int, tuple] = {}  # ``solve``'s work arrays, by rows of the error (3 or 6)

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    def set_q(self, q: np.ndarray) -> None:
        self.data.qpos[self._qpos_index] = q
        mujoco.mj_kinematics(self.model, self.data)

    def site_pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Site position (3,) and orientation (w, x, y, z) at ``q``."""
        self.set_q(q)
        return self._site_pose()

    def _site_pose(self) -> tuple[np.ndarray, np.ndarray]:
        pos = self.data.site_xpos[self.site_id].copy()
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, self.data.site_xmat[self.site_id])
        return pos, quat

    def solve(
        self,
        target_pos: np.ndarray,
        target_quat: np.ndarray | None,
        seed: np.ndarray,
        *,
        position_tolerance: float = 1e-3,
        orientation_tolerance: float = 1e-2,
        max_iterations: int = 150,
        damping: float = 1e-3,
        max_step: float = 0.2,
    ) -> IKResult:
        """Damped least squares from ``seed``, clamped to the joint limits at every step.

        Orientation is ignored when ``target_quat`` is None. Returns the best configuration found; the caller
        checks ``IKResult.within`` (the solver never raises, so seeds can be tried cheaply in turn).
        """
        # Solutions keep LIMIT_MARGIN inside the limits: the servos overshoot a set-point on a limit slightly, and a
        # start configuration past a limit is invalid for the next plan.
        if self._bounds[0] is not self.limits:  # worked out again only when the limits are replaced
            margin = np.minimum(LIMIT_MARGIN, 0.25 * (self.limits[:, 1] - self.limits[:, 0]))
            self._bounds = (self.limits, self.limits[:, 0] + margin, self.limits[:, 1] - margin)
        lo, hi = self._bounds[1:]
        q = np.clip(np.asarray(seed, dtype=float).copy(), lo, hi)
        rows = 3 if target_quat is None else 6
        buffers = self._buffers.get(rows)
        if buffers is None:
            dof = len(self.dof_adr)
            buffers = self._buffers[rows] = (np.zeros(rows), np.empty(rows), np.empty((rows, dof)),
                                             np.empty((rows, rows)), np.empty(dof))
        err, err_w, jac_w, jjt, step_abs = buffers
        damped = self._damped.get((damping, rows))
        if damped is None:
            damped = self._damped[damping, rows] = damping * np.eye(rows)
            damped.flags.writeable = False
        pos_err = rot_err = np.inf
        it = 0
        # The loop runs thousands of times per scene in planning: buffers are reused and numpy's per-call wrappers
        # avoided where the same operation gives the same numbers (norms as sqrt(x·x), as np.linalg.norm computes;
        # quat_error's steps on preallocated quaternions; the linear solve's error state set once per solve; the
        # weighted rows multiplied straight into their buffer, x * 0.2; the sum with the damping, the
        # step's size and the clamped update written in place: the same elementwise operations in the same order).
        m, d, site = self.model, self.data, self.site_id
        qpos, qpos_index, dof_index = d.qpos, self._qpos_index, self._dof_index
        site_pos, site_mat = d.site_xpos[site], d.site_xmat[site]
        jacp, jacr = self._jacp, self._jacr
        quat, conj, diff = self._quat, self._conj, self._diff
        # The position error goes straight into the weighted error (its weight is 1); the rotation error is kept
        # unweighted for its norm and weighted into ``err_w`` after.
        pos_part, rot_part = (err_w[:3] if rows == 6 else err), err[3:]
        rot_w, jac_pos, jac_rot = err_w[3:], jac_w[:3], jac_w[3:]
        with _solve_errors():
            for it in range(1, max_iterations + 1):  # noqa: B007 (the result reports the iterations it ran)
                qpos[qpos_index] = q
                mujoco.mj_kinematics(m, d)
                np.subtract(target_pos, site_pos, out=pos_part)
                pos_err = math.sqrt(pos_part.dot(pos_part))
                if target_quat is not None:
                    mujoco.mju_mat2Quat(quat, site_mat)
                    mujoco.mju_negQuat(conj, quat)
                    mujoco.mju_mulQuat(diff, target_quat, conj)
                    if diff[0] < 0.0:  # the shorter way round
                        np.negative(diff, out=diff)
                    mujoco.mju_quat2Vel(rot_part, diff, 1.0)
                    rot_err = math.sqrt(rot_part.dot(rot_part))
                else:
                    rot_err = 0.0
                if pos_err <= position_tolerance and rot_err <= orientation_tolerance:
                    break
                mujoco.mj_comPos(m, d)  # mj_jacSite needs the com-based frames
                mujoco.mj_jacSite(m, d, jacp, jacr, site)
                # Weight rotation so 1 rad of error counts like 0.2 m: keeps position dominant near the goal.
                if rows == 6:
                    jac_pos[:] = jacp[:, dof_index]
                    np.multiply(jacr[:, dof_index], 0.2, out=jac_rot)
                    np.multiply(rot_part, 0.2, out=rot_w)
                    np.matmul(jac_w, jac_w.T, out=jjt)
                    jjt += damped
                    dq = jac_w.T @ _solve(jjt, err_w)
                else:  # as indexed (its memory order decides the rounding of the products below)
                    jac3 = jacp[:, self.dof_adr]
                    dq = jac3.T @ _solve(jac3 @ jac3.T + damped, err)
                step = np.abs(dq, out=step_abs).max()
                if step > max_step:
                    dq *= max_step / step
                # np.clip's result, without its per-call overhead or a new array per operation
                np.add(q, dq, out=q)
                np.maximum(q, lo, out=q)
                np.minimum(q, hi, out=q)
        return IKResult(q, pos_err, rot_err, it)
