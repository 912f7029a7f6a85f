"""The environment's Gymnasium spaces: the ``IK_JOINT_SERVO`` control action and the proprioceptive observation."""
from __future__ import annotations

import numpy as np
from gymnasium.spaces import Box, Dict

__all__ = ["Box", "control_space", "proprioception_space"]


def control_space() -> Box:
    """(dx, dy, dz, rx, ry, rz, gripper) in [-1, 1]: the pose part scaled to at most 5 cm / 0.5 rad per step;
    gripper -1 opens, 1 closes."""
    return Box(-1.0, 1.0, shape=(7,), dtype=np.float32)


def proprioception_space(arm_dof: int) -> Dict:
    """The built-in proprioception of ``TabletopEnv.observation()`` as arrays (sensor readings left out)."""
    unbounded = dict(low=-np.inf, high=np.inf, dtype=np.float64)
    return Dict({
        "ee_pos": Box(shape=(3,), **unbounded),
        "ee_quat": Box(-1.0, 1.0, shape=(4,), dtype=np.float64),
        "joint_pos": Box(shape=(arm_dof,), **unbounded),
        "joint_vel": Box(shape=(arm_dof,), **unbounded),
        "gripper_command": Box(-1.0, 1.0, shape=(1,), dtype=np.float64),
        "gripper_opening": Box(0.0, np.inf, shape=(1,), dtype=np.float64),
        "held": Box(0, 1, shape=(1,), dtype=np.int8),
    })


def proprioception(env) -> dict[str, np.ndarray]:
    """The arrays of ``proprioception_space`` read from a ``TabletopEnv``."""
    pose = env.ee_pose()
    return {"ee_pos": pose.pos.astype(np.float64), "ee_quat": np.clip(pose.quat, -1.0, 1.0).astype(np.float64),
            "joint_pos": env.arm_q().astype(np.float64), "joint_vel": env.arm_qd().astype(np.float64),
            "gripper_command": np.array([env.gripper_command], dtype=np.float64),
            "gripper_opening": np.array([max(0.0, env.gripper_opening())], dtype=np.float64),
            "held": np.array([env.held_object is not None], dtype=np.int8)}
