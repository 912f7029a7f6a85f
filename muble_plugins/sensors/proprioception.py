"""What the robot knows about itself: wrist wrench, gripper, end-effector pose, joint state."""
from __future__ import annotations

from typing import Any

import numpy as np

from muble import Sensor


class WristForceTorque(Sensor):
    """The wrist force/torque sensor in the world frame; ``force_tared`` subtracts the last tare (if any)."""

    def read(self, env) -> dict[str, Any]:
        force, torque = env.wrist_wrench()
        tare = env.tare_force if env.tare_force is not None else np.zeros(3)
        return {"force": force, "torque": torque, "force_tared": force - tare}


class GripperState(Sensor):
    def read(self, env) -> dict[str, Any]:
        return {"command": env.gripper_command, "opening": env.gripper_opening(), "held_object": env.held_object}


class EndEffectorPose(Sensor):
    def read(self, env) -> dict[str, Any]:
        pose = env.ee_pose()
        return {"position": pose.pos, "quaternion": pose.quat}


class JointState(Sensor):
    def read(self, env) -> dict[str, Any]:
        return {"position": env.arm_q(), "velocity": env.arm_qd()}
