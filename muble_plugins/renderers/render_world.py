"""Self-contained worlds for renderers: a robosuite Panda, a table and primitive objects, and small rigs of the
material classes.

The reference sheet (``muble_plugins.renderers.blender.reference_sheet``) renders them, and renderer tests and
benchmarks compare renderers on them, on real robot meshes without the full environment. Object bodies are named
``obj<id>...`` like the environment's, so the usual geom-to-label mapping applies.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from muble.core import streams
from muble.core.errors import SceneValidationError
from muble.core.scene import SceneGraph, SceneObject
from muble.stage.geometry import yaw_quat

if TYPE_CHECKING:  # pragma: no cover
    import mujoco

COLOURS = {"red": (0.85, 0.12, 0.1), "blue": (0.12, 0.3, 0.85), "green": (0.15, 0.65, 0.2),
           "yellow": (0.95, 0.8, 0.1), "white": (0.92, 0.92, 0.9), "brown": (0.55, 0.33, 0.15),
           "grey": (0.55, 0.55, 0.57), "purple": (0.5, 0.2, 0.65)}
MATERIALS = ("plastic", "metal", "glass", "rubber", "wood", "ceramic")
SHAPES = ("cuboid", "cylindrical", "hemisphere")
# The worlds' streams (muble.core.streams), keyed by the caller's seed.
WORLD_STREAM = streams.declare("render.world", "a renderer world's objects: places, turns, shapes, sizes, "
                               "materials and colours (seed; muble_plugins.renderers.render_world)")
ARM_STREAM = streams.declare("render.world_arm", "a renderer world's arm pose about its home pose (arm_seed)")


def world_rng(seed: int) -> np.random.Generator:
    """The generator ``random_scene`` draws world ``seed`` from."""
    return streams.stream(WORLD_STREAM, seed)
TABLE_TOP_Z = 0.8
ROBOT_BASE = (-0.56, 0.0, 0.0)


def random_scene(rng: np.random.Generator, n_objects: int = 4, image_index: int = 0) -> SceneGraph:
    """Objects spread over the table without overlap, with random shape, colour and material."""
    objects: list[SceneObject] = []
    placed: list[np.ndarray] = []
    while len(objects) < n_objects:
        xy = rng.uniform([-0.2, -0.3], [0.25, 0.3])
        if any(np.linalg.norm(xy - p) < 0.12 for p in placed):
            continue
        placed.append(xy)
        yaw = rng.uniform(-np.pi, np.pi)
        shape = str(rng.choice(SHAPES))
        half = rng.uniform(0.025, 0.045, size=3)
        objects.append(SceneObject(
            id=len(objects), model=f"{shape}_primitive", name="block", shape=shape, size="medium-sized",
            material=str(rng.choice(MATERIALS)), colour=str(rng.choice(list(COLOURS))),
            position=np.array([xy[0], xy[1], 0.0]),
            orientation=yaw_quat(yaw),
            weight_gt=100.0, stackable=False, stack_base=False, pickupable=True,
            bbox={"x": float(2 * half[0]), "y": float(2 * half[1]), "z": float(2 * half[2])}))
    return SceneGraph(objects=objects, split="test", image_index=image_index)


def build_world(scene: SceneGraph, arm_seed: int | None = None) -> tuple["mujoco.MjModel", "mujoco.MjData"]:
    """Compile the robot, table and the scene's objects; the arm is posed near its home pose."""
    import mujoco
    from robosuite.models.arenas import TableArena
    from robosuite.models.bases import robot_base_factory
    from robosuite.models.grippers import gripper_factory
    from robosuite.models.objects import BallObject, BoxObject, CylinderObject
    from robosuite.models.robots import Panda
    from robosuite.models.tasks import ManipulationTask

    robot = Panda(idn=0)
    # The environment's mount (muble.sim.world): without it the arm stands on the floor, under the table.
    robot.add_base(base=robot_base_factory(robot.default_base, idn=0))
    robot.add_gripper(gripper_factory("PandaGripper", idn=0))
    robot.set_base_xpos(list(ROBOT_BASE))
    arena = TableArena(table_full_size=(0.8, 0.8, 0.05), table_offset=(0, 0, TABLE_TOP_Z))
    bodies = []
    for obj in scene.objects:
        if not isinstance(obj.bbox, dict):
            raise SceneValidationError(f"a renderer world builds objects from their extents {{x, y, z}}, not "
                                       f"{obj.bbox!r}", obj=obj.id, field="bbox")
        half = [obj.bbox["x"] / 2, obj.bbox["y"] / 2, obj.bbox["z"] / 2]
        rgba = [*COLOURS.get(obj.colour, (0.5, 0.5, 0.5)), 1.0]
        name = f"obj{obj.id}"
        if obj.shape == "cylindrical":
            bodies.append(CylinderObject(name=name, size=[min(half[:2]), half[2]], rgba=rgba))
        elif obj.shape == "hemisphere":
            bodies.append(BallObject(name=name, size=[min(half)], rgba=rgba))
        else:
            bodies.append(BoxObject(name=name, size=half, rgba=rgba))
    task = ManipulationTask(mujoco_arena=arena, mujoco_robots=[robot], mujoco_objects=bodies)
    model = mujoco.MjModel.from_xml_string(task.get_xml())
    data = mujoco.MjData(model)
    rng = None if arm_seed is None else streams.stream(ARM_STREAM, arm_seed)
    for joint, q in zip(robot.joints, robot.init_qpos):
        noise = 0.0 if rng is None else rng.uniform(-0.3, 0.3)
        data.joint(joint).qpos = q + noise
    for obj, body in zip(scene.objects, bodies):
        lowest = body.bottom_offset[2]
        pos = np.array([obj.position[0], obj.position[1], TABLE_TOP_Z - lowest])
        data.joint(body.joints[0]).qpos = np.concatenate([pos, obj.orientation])
    mujoco.mj_forward(model, data)
    return model, data


def material_rig(rgb: tuple[float, float, float] = (0.8, 0.25, 0.15), fovy: float = 45.0
                 ) -> tuple[SceneGraph, "mujoco.MjModel", "mujoco.MjData"]:
    """One sphere and one box per material class, same colour, in a row on a grey table, seen by camera
    ``materials``: the material classes side by side under the same light."""
    bodies, objects = [], []
    for i, material in enumerate(MATERIALS):
        x = (i - (len(MATERIALS) - 1) / 2) * 0.16
        bodies.append(f"""
        <body name="obj{i}" pos="{x:.3f} 0 0.06">
          <geom type="sphere" size="0.05" rgba="{rgb[0]} {rgb[1]} {rgb[2]} 1" group="1"/>
          <geom type="box" size="0.04 0.02 0.03" pos="0 0.09 -0.03" rgba="{rgb[0]} {rgb[1]} {rgb[2]} 1"
                group="1"/>
        </body>""")
        objects.append(SceneObject(
            id=i, model="sphere", name="ball", shape="sphere", size="medium-sized", material=material,
            colour="red", position=np.array([x, 0.0, 0.06]), orientation=np.array([1.0, 0, 0, 0]),
            weight_gt=100.0, stackable=False, stack_base=False, pickupable=True))
    xml = f"""
    <mujoco>
      <worldbody>
        <body name="table">
          <geom type="box" size="0.6 0.25 0.01" pos="0 0.05 -0.01" rgba="0.5 0.5 0.5 1" group="1"/>
        </body>
        {''.join(bodies)}
        <camera name="materials" pos="0 -0.55 0.32" xyaxes="1 0 0 0 0.5 0.866" fovy="{fovy}"/>
      </worldbody>
    </mujoco>"""
    return SceneGraph(objects=objects, split="materials"), *_compiled(xml)


def glass_slab_rig() -> tuple[SceneGraph, "mujoco.MjModel", "mujoco.MjData"]:
    """A glass slab resting on a grey table (its base in the table's top face), seen from above at an angle by
    camera ``above``."""
    xml = """
    <mujoco>
      <worldbody>
        <body name="table">
          <geom type="box" size="0.3 0.3 0.01" pos="0 0 -0.01" rgba="0.6 0.6 0.6 1" group="1"/>
        </body>
        <body name="obj0" pos="0 0 0.008">
          <geom type="box" size="0.05 0.05 0.008" rgba="0.9 0.9 0.9 1" group="1"/>
        </body>
        <camera name="above" pos="0 -0.25 0.35" xyaxes="1 0 0 0 0.8 0.6" fovy="40"/>
      </worldbody>
    </mujoco>"""
    slab = SceneObject(id=0, model="slab", name="slab", shape="cuboid", size="medium-sized", material="glass",
                       colour="transparent", position=np.array([0.0, 0.0, 0.008]),
                       orientation=np.array([1.0, 0, 0, 0]), weight_gt=100.0, stackable=False, stack_base=False,
                       pickupable=True)
    return SceneGraph(objects=[slab], split="glass"), *_compiled(xml)


def _compiled(xml: str) -> tuple["mujoco.MjModel", "mujoco.MjData"]:
    """The model of an MJCF string and its data at the initial state, forward kinematics done."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data
