"""Built-in sensors: wrist force/torque, gripper state, EE pose, joints, object state, weight and stiffness."""
from muble import PluginRecord, hookimpl


@hookimpl
def muble_register_sensors() -> list[PluginRecord]:
    from muble_plugins.sensors.proprioception import EndEffectorPose, GripperState, JointState, WristForceTorque
    from muble_plugins.sensors.objects import ObjectState
    from muble_plugins.sensors.measurements import Stiffness, Weight

    return [
        PluginRecord("wrist_ft", WristForceTorque, "wrist force (N) and torque (N·m), world frame, minus tare"),
        PluginRecord("gripper", GripperState, "gripper command, pad opening (m) and held object"),
        PluginRecord("ee_pose", EndEffectorPose, "end-effector position and quaternion (w, x, y, z)"),
        PluginRecord("joints", JointState, "arm joint positions (rad) and velocities (rad/s)"),
        PluginRecord("objects", ObjectState, "object poses, world bbox extents, in-hand and raised flags"),
        PluginRecord("weight", Weight, "measured weights (g) from the wrist force sensor, per object"),
        PluginRecord("stiffness", Stiffness, "measured stiffness (N/m) from squeezing, per object"),
    ]
