"""The tabletop world as MJCF: a robosuite table arena, a robosuite single-arm robot with its gripper, the scene's
objects, cameras and lights, compiled to one ``MjModel``.

Frames: the MuJoCo world frame *is* the scene frame of SHOP-VRB2: the table top is the plane z = 0, the robot's
root sits at the origin (x forward over the table), and object positions are the scene graph's ``3d_coords``.
robosuite builds its arena with the floor at z = 0; everything it places is shifted down by the table height.
"""
from __future__ import annotations

import copy
import logging
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import mujoco
import numpy as np

from muble.core.errors import ConfigError, unknown_name
from muble.core.objects import ObjectModel
from muble.core.scene import SceneGraph
from muble.sim.object_mjcf import object_mjcf
from muble.stage.camera import CameraParams
from muble.stage.table import STAGE_KEY, UNNAMED_STAGE, Stage, stage_name, stage_named

logger = logging.getLogger(__name__)

ROBOTS = ("Panda", "Sawyer", "UR5e", "Kinova3", "IIWA")
TABLE_HEIGHT = 0.8  # m, robosuite's table; the floor lies this far below the table top
FRONT_CAMERA = "front"
WRIST_CAMERA = "wrist"


TABLE_GEOM = "table_collision"  # robosuite's TableArena names its top's collision geom so


def scene_stage(scene: SceneGraph, override: str | None = None) -> Stage:
    """The stage ``scene`` is built on: ``override`` (``robot.stage``) when given, else its file's ``stage`` key,
    else ``original`` for a scene of the original release's files (which name none; they were made on it), else
    ``UNNAMED_STAGE``."""
    if override:
        return stage_named(override)
    return stage_named(stage_name(scene),
                       f"scene {scene.image_index}'s '{STAGE_KEY}' key; or build it on another with the "
                       "environment's robot.stage setting, TabletopEnv(..., stage=NAME)")


def object_weld_name(obj_id: int) -> str:
    return f"grasp_object{obj_id}"


@dataclass
class WorldNames:
    """Names and addresses in the compiled model that the environment, sensors and planners use."""

    robot: str
    arm_joints: list[str]
    arm_actuators: list[str]
    gripper_joints: list[str]
    gripper_actuators: list[str]
    ee_site: str  # the grip site between the fingers
    hand_body: str  # body the F/T sensor measures and grasped objects weld to
    force_sensor: str
    torque_sensor: str
    left_pads: list[str]  # finger pad geoms
    right_pads: list[str]
    robot_geom_prefixes: tuple[str, ...]
    table_geom: str = TABLE_GEOM  # the table top's collision geom
    objects: dict[int, str] = field(default_factory=dict)  # scene id -> body name
    welds: dict[int, str] = field(default_factory=dict)  # scene id -> weld equality name
    cameras: dict[str, str] = field(default_factory=dict)  # role -> MuJoCo camera name
    init_qpos: np.ndarray | None = None
    gripper_format: object = None  # the robosuite gripper model (its ``format_action`` maps -1..1)
    stage: str = UNNAMED_STAGE  # the ``muble.stage.table.STAGES`` entry the world stands on


def _fmt(values) -> str:
    return " ".join(f"{float(v):.9g}" for v in np.asarray(values).reshape(-1))


def _shift_down(worldbody: ET.Element, dz: float) -> None:
    for child in worldbody:
        if child.tag in ("body", "geom", "site", "camera", "light"):
            pos = np.fromstring(child.get("pos", "0 0 0"), sep=" ")
            pos[2] -= dz
            child.set("pos", _fmt(pos))


def _camera_element(name: str, params: dict | None) -> ET.Element:
    """The scene's camera (``camera_params``: position, Blender EulerXYZ degrees, image size and lens) in MuJoCo:
    both look down -Z with +Y up, so the rotation carries over and the lens becomes MuJoCo's vertical fovy."""
    camera = CameraParams.from_scene_params(params)
    return ET.Element("camera", name=name, mode="fixed", pos=_fmt(camera.position), quat=_fmt(camera.mujoco_quat),
                      fovy=f"{camera.fovy_deg:.9g}")


def build_world(scene: SceneGraph, models: dict[int, ObjectModel], robot: str = "Panda",
                gripper: str | None = None, timestep: float = 0.002,
                visual: bool = True, stage: str | None = None) -> tuple[mujoco.MjModel, WorldNames]:
    """Compile the tabletop world of ``scene``; ``models`` maps each scene object id to its built model.

    ``visual=False`` leaves out what only a renderer sees (MuJoCo's ``discardvisual``: geoms that collide with
    nothing and weigh nothing, their meshes, materials and textures): the physics, contacts, rays on collision
    geoms and kinematics are the same, the model compiles in about half the time, and nothing can be drawn.
    ``stage`` names the ``muble.stage.table.STAGES`` entry to stand on (``None``: the scene's own,
    ``scene_stage``)."""
    if robot not in ROBOTS:
        raise ConfigError(unknown_name("robot", robot, ROBOTS))
    stage = scene_stage(scene, stage)
    world, names = _staged_robot(robot, gripper, stage)

    world.worldbody.append(_camera_element(FRONT_CAMERA, scene.camera_params))
    names.cameras = {FRONT_CAMERA: FRONT_CAMERA, WRIST_CAMERA: names.robot_geom_prefixes[0] + "eye_in_hand"}
    energy = scene.extra.get("lamp_energy") or {}  # per lamp, relative to its default brightness
    for lamp, pos in (scene.lamp_params or {}).items():
        if isinstance(pos, (list, tuple)) and len(pos) == 3:
            diffuse = 0.4 * float(energy.get(lamp, 1.0))
            ET.SubElement(world.worldbody, "light", name=f"lamp_{lamp}", pos=_fmt(pos), dir=_fmt(-np.asarray(pos)),
                          directional="false", castshadow="true", diffuse=_fmt([diffuse] * 3))

    missing = [o.id for o in scene.objects if o.id not in models]
    if missing:
        raise ConfigError(f"no object model for scene object(s) {missing}; build one per scene object")
    for obj in scene.objects:
        fragment = object_mjcf(models[obj.id], obj.id, obj.position, obj.orientation)
        for mesh in ET.fromstring(f"<asset>{fragment.asset_xml}</asset>"):
            world.asset.append(mesh)
        for body in ET.fromstring(f"<worldbody>{fragment.body_xml}</worldbody>"):  # the contents' body too
            world.worldbody.append(body)
        names.objects[obj.id] = fragment.body_name

    # MuJoCo cancels gravity on the robot's links (its bodies must be marked before compiling: the compiler
    # counts them); held objects are not compensated, their weight is what the wrist sensor measures.
    for body in world.worldbody.iter("body"):
        if body.get("name", "").startswith(names.robot_geom_prefixes[:2]):
            body.set("gravcomp", "1")

    _couple_linkage_fingers(world, names)
    if not visual:
        world.root.find("compiler").set("discardvisual", "true")
    model = _compile(world, names, timestep)
    if type(names.gripper_format).__name__ == "Robotiq85Gripper":
        for side in ("left", "right"):  # pinned to the finger in the real linkage, never touching it
            g = model.geom(f"{names.robot_geom_prefixes[1]}{side}_inner_knuckle_collision").id
            model.geom_contype[g] = model.geom_conaffinity[g] = 0
    return model, names


# The robot, its gripper and the stage's table as robosuite builds them (most of building a world before it is
# compiled, and the same for every scene), by (robot, gripper, stage): each world gets a deep copy, which is what
# building them again gives (a gripper model keeps its action state, so even that is never shared).
_staged_robots: dict[tuple[str, str | None, str], tuple] = {}


def _staged_robot(robot: str, gripper: str | None, stage: Stage):
    """(robosuite world with the table and the robot on its stage, its ``WorldNames``), a fresh copy."""
    key = (robot, gripper, stage.name)
    if key not in _staged_robots:
        _staged_robots[key] = _build_staged_robot(robot, gripper, stage)
    return copy.deepcopy(_staged_robots[key])


def _build_staged_robot(robot: str, gripper: str | None, stage: Stage):
    from robosuite.models import MujocoWorldBase
    from robosuite.models.arenas import TableArena
    from robosuite.models.bases import robot_base_factory
    from robosuite.models.grippers import gripper_factory
    from robosuite.models.robots import create_robot

    robot_model = create_robot(robot, idn=0)
    robot_model.add_base(base=robot_base_factory(robot_model.default_base if stage.mount else "NullMount", idn=0))
    gripper_name = gripper or stage.gripper or robot_model.default_gripper["right"]
    try:
        gripper_model = gripper_factory(gripper_name, idn="0_right")
    except Exception as e:  # robosuite raises a bare ValueError listing nothing
        raise ConfigError(f"robosuite has no gripper '{gripper_name}' ({e}); leave robot.gripper unset for the "
                          f"robot's default") from e
    robot_model.add_gripper(gripper_model, robot_model.eef_name["right"])
    if stage.table_centre_x is None:
        offset = np.asarray(robot_model.base_xpos_offset["table"](stage.table_size[0]), dtype=float)
        robot_model.set_base_xpos([0.0, 0.0, offset[2]])  # the table centre moves instead, to x = -offset
        table_offset = (-offset[0], -offset[1], TABLE_HEIGHT)
    else:
        robot_model.set_base_xpos([0.0, 0.0, TABLE_HEIGHT if not stage.mount else 0.0])
        table_offset = (stage.table_centre_x, 0.0, TABLE_HEIGHT)
    arena = TableArena(table_full_size=stage.table_size, table_offset=table_offset)

    world = MujocoWorldBase()
    world.merge(arena)
    world.merge(robot_model)
    _shift_down(world.worldbody, TABLE_HEIGHT)

    names = WorldNames(
        robot=robot,
        arm_joints=list(robot_model.joints),
        arm_actuators=list(robot_model.actuators),
        gripper_joints=list(gripper_model.joints),
        gripper_actuators=list(gripper_model.actuators),
        ee_site=gripper_model.important_sites["grip_site"],
        hand_body="",
        force_sensor=gripper_model.naming_prefix + "force_ee",
        torque_sensor=gripper_model.naming_prefix + "torque_ee",
        left_pads=list(gripper_model.important_geoms["left_fingerpad"]),
        right_pads=list(gripper_model.important_geoms["right_fingerpad"]),
        robot_geom_prefixes=(robot_model.naming_prefix, gripper_model.naming_prefix, "mount0_"),
        init_qpos=np.asarray(stage.start_qpos.get(robot, robot_model.init_qpos), dtype=float),
        gripper_format=gripper_model,
        stage=stage.name,
    )
    return world, names


# N m the Robotiq 85's finger drive may exert: about 20 N on each pad (measured across a 77 mm glass), the real
# gripper's lowest grip force and the Panda gripper's (20 N a finger). robosuite's servo has no limit and squeezes
# with up to ~300 N a pad; the jaw law holds force = stiffness x depth (a glass is 17-90 kN/m), so the fingertips
# sank into a glass's 3-6 mm wall and left it wedged on them: tipped over, or held up, as the fingers opened.
ROBOTIQ_TORQUE = 1.0
# s, time constant of the joint equalities that close the Robotiq 85's four-bar linkage (robosuite's tendon
# replaced, see _couple_linkage_fingers). The linkage gives: a pad tilts by ~1.3 mrad per 5 N (30 um from one end
# of the pad to the other, as much as a 70-110 kN/m glass or mug yields to the same 5 N), which squeeze allows for
# (muble_plugins.primitives.measure.jaw_travel). Stiffer, 0.006 s, halved the tilt but the fingers then closed on
# nothing at a bowl's rim (tests/tasks/test_tasks_oracle_physics.py, stack_order on the original stage).
LINKAGE_TIMECONST = 0.01


def _couple_linkage_fingers(world, names: WorldNames) -> None:
    """Make robosuite's Robotiq 85 a parallel gripper. As shipped, its four-bar fingers are held together by a
    weak tendon only; each inner finger rubs on its inner knuckle, is driven against the tendon's range, and the
    jaws stall 7-9 cm apart. Joint equalities close the four-bar linkage as in the real gripper: the inner knuckle
    turns with the driven knuckle and the inner finger turns back by as much, keeping the pads parallel."""
    if type(names.gripper_format).__name__ != "Robotiq85Gripper":
        return
    prefix = names.robot_geom_prefixes[1]
    for tendon in world.root.iter("fixed"):  # superseded by the equalities, which it would fight
        tendon.set("limited", "false")
        tendon.set("stiffness", "0")
    for driven, side in (("finger_joint", "left"), ("right_outer_knuckle_joint", "right")):
        for joint, coef in ((f"{side}_inner_knuckle_joint", 1.0), (f"{side}_inner_finger_joint", -1.0)):
            ET.SubElement(world.equality, "joint", joint1=prefix + joint, joint2=prefix + driven,
                          polycoef=f"0 {coef} 0 0 0", solref=f"{LINKAGE_TIMECONST:g} 1")
    # The finger links weigh 15-30 g: rotor inertia keeps the closed chain stable at 2 ms. The drive is limited to
    # ROBOTIQ_TORQUE and damped so that the jaws close in ~0.3 s at up to ~0.16 m/s each, about the real gripper's
    # top speed (150 mm/s); undamped they slam (~1 m/s, which throws a mug off the table).
    joints = {prefix + j for j in ("finger_joint", "right_outer_knuckle_joint", "left_inner_knuckle_joint",
                                   "right_inner_knuckle_joint", "left_inner_finger_joint", "right_inner_finger_joint")}
    for joint in world.root.iter("joint"):
        if joint.get("name") in joints:
            joint.set("armature", "0.001")
            joint.set("damping", "0.3")
    for actuator in world.actuator.iter("position"):
        if actuator.get("joint") in (prefix + "finger_joint", prefix + "right_outer_knuckle_joint"):
            actuator.set("forcelimited", "true")
            actuator.set("forcerange", f"{-ROBOTIQ_TORQUE:.9g} {ROBOTIQ_TORQUE:.9g}")
    # The pad covers the fingertip's whole inner face, as the real gripper's does. As shipped it is 2 mm narrower and
    # shorter than the fingertip box it sits on, and stands only 0.3 mm proud of it: on a concave face (inside a
    # glass's rim) the fingertip's edges touch first, the pad never does, and the grasp never engages.
    geoms = {g.get("name"): g for g in world.worldbody.iter("geom")}
    for side in ("left", "right"):
        pad, tip = geoms[f"{prefix}{side}_fingerpad_collision"], geoms[f"{prefix}{side}_fingertip_collision"]
        pad_size, tip_size = (np.fromstring(g.get("size"), sep=" ") for g in (pad, tip))
        pad.set("size", _fmt([tip_size[0], pad_size[1], tip_size[2]]))  # its thickness (y) kept


def _sensor_body(world, sensor: str) -> str:
    """Name of the body that holds the site of ``sensor``, read from the MJCF (no compile needed)."""
    site = next((e.get("site") for e in world.root.iter() if e.get("name") == sensor and e.get("site")), None)
    for body in world.worldbody.iter("body"):
        if any(child.tag == "site" and child.get("name") == site for child in body):
            return body.get("name")
    probe = mujoco.MjModel.from_xml_string(world.get_xml())  # a layout the search above does not know
    return probe.body(probe.site_bodyid[probe.sensor(sensor).objid[0]]).name


def _compile(world, names: WorldNames, timestep: float) -> mujoco.MjModel:
    equality = world.equality
    # The hand body is the one carrying the F/T sensor site: a weld to it loads the sensor with the held weight.
    names.hand_body = _sensor_body(world, names.force_sensor)
    for obj_id, body in names.objects.items():
        weld = object_weld_name(obj_id)
        # Declared inactive; the environment sets the relative pose and switches it on at grasp time.
        ET.SubElement(equality, "weld", name=weld, body1=names.hand_body, body2=body, active="false",
                      solref="0.004 1", solimp="0.99 0.999 0.001")
        names.welds[obj_id] = weld
    model = mujoco.MjModel.from_xml_string(world.get_xml())
    model.opt.timestep = timestep
    # Implicit-in-velocity integration keeps the stiff joint servos and contact damping stable at 2 ms.
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    # No fluid forces. robosuite's base world sets air's density and viscosity, and MuJoCo then drags every body as
    # the box of its inertia; the Panda model's placeholder inertias make boxes of 0.8 to 2.5 m of the hand and
    # finger tips, whose drag (about 10 N m about the last joint at 1 rad/s) saturates the 12 N m wrist actuator:
    # the wrist fell a radian behind a planned turn. Real air drag on a tabletop arm and objects is negligible.
    model.opt.density = 0.0
    model.opt.viscosity = 0.0
    return model
