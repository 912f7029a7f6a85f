"""A compact tabletop scene for planner tests and benchmarks: one robosuite arm, its gripper, a table, boxes.

This stands alone (it does not need the full environment): planners can be exercised on a real robot model
with obstacles in a second.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np


@dataclass
class Tabletop:
    """A compiled tabletop model and the names a ``MujocoCollisionWorld`` needs."""

    model: mujoco.MjModel
    data: mujoco.MjData
    arm_joints: list[str]
    ee_site: str
    robot_root: str
    gripper_root: str
    home_q: np.ndarray
    table_top_z: float
    box_bodies: list[str] = field(default_factory=list)
    object_bodies: list[str] = field(default_factory=list)

    def collision_world(self, **options):
        from muble.sim.collision_world import MujocoCollisionWorld

        return MujocoCollisionWorld(
            self.model, self.data, self.arm_joints, self.ee_site, self.robot_root, self.gripper_root, **options
        )


def build_tabletop(
    robot: str = "Panda",
    boxes: list[tuple[tuple[float, float, float], tuple[float, float, float]]] = (),
    table_size: tuple[float, float, float] = (0.8, 0.8, 0.05),
    table_height: float = 0.8,
    free_boxes: list[tuple[tuple[float, float, float], tuple[float, float, float]]] = (),
) -> Tabletop:
    """Compile ``robot`` beside a table carrying ``boxes`` given as ((x, y, z) centre, (hx, hy, hz) half-size).

    Box centres are in world coordinates; ``boxes`` are fixed obstacles (no joint), ``free_boxes`` have a free
    joint (objects that can be grasped and held) and are named ``object<i>_main``.
    """
    from robosuite.models.arenas import TableArena
    from robosuite.models.bases import robot_base_factory
    from robosuite.models.grippers import gripper_factory
    from robosuite.models.objects import BoxObject
    from robosuite.models.robots import create_robot
    from robosuite.models.tasks import ManipulationTask

    arm = create_robot(robot, idn=0)
    arm.add_base(base=robot_base_factory(arm.default_base, idn=0))
    arm.update_joints()
    arm.update_actuators()
    gripper = gripper_factory(arm.default_gripper["right"], idn="0_right")
    arm.add_gripper(gripper, arm.eef_name["right"])
    arm.set_base_xpos(arm.base_xpos_offset["table"](table_size[0]))
    arena = TableArena(table_full_size=table_size, table_offset=(0, 0, table_height))
    objects = [BoxObject(name=f"obstacle{i}", size=list(half), rgba=[0.8, 0.2, 0.2, 1], joints=None)
               for i, (_, half) in enumerate(boxes)]
    free = [BoxObject(name=f"object{i}", size=list(half), rgba=[0.2, 0.6, 0.2, 1])
            for i, (_, half) in enumerate(free_boxes)]
    task = ManipulationTask(mujoco_arena=arena, mujoco_robots=[arm], mujoco_objects=objects + free)
    for obj, (centre, _) in zip(objects, boxes):
        obj.get_obj().set("pos", " ".join(str(v) for v in centre))
    model = task.get_model(mode="mujoco")
    data = mujoco.MjData(model)
    arm_joints = list(arm.arm_joints)
    home = np.asarray(arm.init_qpos, dtype=float)
    for name, value in zip(arm_joints, home):
        data.qpos[model.joint(name).qposadr[0]] = value
    for obj, (centre, _) in zip(free, free_boxes):
        adr = model.joint(obj.joints[0]).qposadr[0]
        data.qpos[adr : adr + 7] = [*centre, 1.0, 0.0, 0.0, 0.0]
    mujoco.mj_forward(model, data)
    return Tabletop(
        model=model,
        data=data,
        arm_joints=arm_joints,
        ee_site=gripper.important_sites["grip_site"],
        robot_root=arm.root_body,
        gripper_root=gripper.root_body,
        home_q=home,
        table_top_z=table_height,
        box_bodies=[o.root_body for o in objects],
        object_bodies=[o.root_body for o in free],
    )
