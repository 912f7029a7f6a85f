"""Scenes without an object set, for tests of anything that needs an environment: ``simple_object_model`` (a
solid box or cylinder as an ``ObjectModel``), ``simple_scene`` (a scene graph of such models) and
``five_object_scene``."""
from __future__ import annotations

import numpy as np

from muble.core.objects import GraspFrame, MeshPart, ObjectModel, ObjectSpec
from muble.core.scene import SceneGraph, SceneObject


def simple_object_model(shape: str = "box", size=(0.05, 0.05, 0.08), weight_g: float = 200.0,
                        stiffness: float = 5000.0, damping: float = 20.0, friction: float = 1.0,
                        rgba=(0.8, 0.2, 0.2, 1.0)) -> ObjectModel:
    """A solid box or cylinder (``size`` = full x, y, z extents; a cylinder uses x as its diameter), origin at
    the centre of its base, with exact mass and the inertia of a uniform solid."""
    import trimesh

    sx, sy, sz = (float(s) for s in size)
    if shape == "box":
        mesh = trimesh.creation.box(extents=(sx, sy, sz))
    elif shape == "cylinder":
        mesh = trimesh.creation.cylinder(radius=sx / 2, height=sz, sections=24)
        sy = sx
    else:
        raise ValueError(f"unknown simple shape '{shape}'; valid: box, cylinder")
    mesh.apply_translation((0.0, 0.0, sz / 2))
    mass = weight_g / 1000.0
    mesh.density = mass / mesh.volume
    part = MeshPart(np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=int))
    spec = ObjectSpec("simple", shape, f"{shape}_{sx:.3f}x{sy:.3f}x{sz:.3f}", "red", "plastic", "small",
                      "cuboid" if shape == "box" else "cylindrical", 1.0, weight_g, stiffness, friction)
    return ObjectModel(
        spec=spec, visual=part, collision_parts=[part], mass=mass,
        com=np.asarray(mesh.center_mass, dtype=float), inertia=np.asarray(mesh.moment_inertia, dtype=float),
        friction=friction, stiffness=stiffness, damping=damping, rgba=tuple(rgba), material_class="plastic",
        grasp_type="box" if shape == "box" else "cylinder",
        grasp_frames=[GraspFrame(np.array([0.0, 0.0, sz / 2]), np.array([0.0, 1.0, 0.0, 0.0]), max(sx, sy))],
        pickupable=True, stackable=shape == "box", stack_base=shape == "box", extents=np.array([sx, sy, sz]),
    )


def simple_scene(positions, models: list[ObjectModel]) -> SceneGraph:
    """A scene graph placing ``models[i]`` at ``positions[i]`` (x, y on the table top)."""
    objects = []
    for i, (xy, m) in enumerate(zip(positions, models)):
        objects.append(SceneObject(
            id=i, model=m.spec.model, name=m.spec.category, shape=m.spec.shape, size=m.spec.size,
            material=m.spec.material, colour=m.spec.colour, position=np.array([xy[0], xy[1], 0.0]),
            orientation=np.array([1.0, 0.0, 0.0, 0.0]), weight_gt=m.spec.weight_g, stackable=m.stackable,
            stack_base=m.stack_base, pickupable=m.pickupable, stiffness=m.stiffness,
            bbox={"x": float(m.extents[0]), "y": float(m.extents[1]), "z": float(m.extents[2])},
        ))
    return SceneGraph(objects=objects)


def five_object_scene() -> tuple[SceneGraph, dict[int, ObjectModel]]:
    """Five boxes and cylinders of different weights within reach of every supported robot."""
    models = [
        simple_object_model("box", (0.05, 0.05, 0.08), 180.0, 4000.0),
        simple_object_model("cylinder", (0.06, 0.06, 0.10), 320.0, 8000.0, rgba=(0.2, 0.6, 0.2, 1)),
        simple_object_model("box", (0.04, 0.06, 0.05), 95.5, 2500.0, rgba=(0.2, 0.2, 0.8, 1)),
        simple_object_model("cylinder", (0.05, 0.05, 0.07), 234.5, 12000.0, rgba=(0.8, 0.8, 0.2, 1)),
        simple_object_model("box", (0.06, 0.05, 0.04), 410.0, 6000.0, rgba=(0.5, 0.3, 0.1, 1)),
    ]
    positions = [(0.45, 0.0), (0.55, -0.2), (0.40, 0.22), (0.65, 0.12), (0.35, -0.25)]
    scene = simple_scene(positions, models)
    return scene, {o.id: m for o, m in zip(scene.objects, models)}
