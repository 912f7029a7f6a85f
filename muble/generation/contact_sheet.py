"""A contact sheet: generated scenes drawn by a renderer from the task camera, tiled into one PNG."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from muble.core.objects import ObjectModel, ObjectSpec
from muble.core.scene import SceneGraph
from muble.generation import checks
from muble.stage.camera import CameraParams
from muble.stage.layout import Placement


def models_from_scene(object_set, scene: SceneGraph) -> list[ObjectModel]:
    """Rebuild each object's model from the scene file's attributes (mass from ``weight_gt``)."""
    models = []
    for o in scene.objects:
        if o.weight_gt is None:  # an agent's view of a scene (muble.core.observation) hides the weights
            raise ValueError(f"object {o.id} ({o.name}) of scene {scene.image_index} has no weight_gt: its model "
                             "is rebuilt from a generated scene file, which records every object's weight")
        spec = ObjectSpec(object_set=scene.extra.get("generator", {}).get("object_set", ""), category=o.name,
                          model=o.model, colour=o.colour, material=o.material, size=o.size, shape=o.shape,
                          scale=float(o.scale_factor or 1.0), weight_g=o.weight_gt, stiffness=o.stiffness or 1e4)
        models.append(object_set.build(spec))
    return models


def placements_from_scene(scene: SceneGraph) -> list[Placement]:
    return [Placement(float(o.position[0]), float(o.position[1]), float(o.yaw)) for o in scene.objects]


def write_contact_sheet(path: str | Path, scenes: list[SceneGraph], object_set, renderer: str,
                        renderer_options: dict | None = None, columns: int = 4, scale: float = 0.5,
                        table_x=(0.0, 0.9), table_y=(-0.6, 0.6)) -> Path:
    """Draw ``scenes`` at ``scale`` of their camera's size and save them as one PNG grid; returns the path.

    ``renderer`` is the registry name of a renderer that draws MuJoCo models (``renderer_options`` its options
    besides the size), e.g. the generator config's."""
    from PIL import Image, ImageDraw

    from muble.plugins.registry import get_registry

    if not scenes:
        raise ValueError("no scenes to draw")
    camera = CameraParams.from_scene_params(scenes[0].camera_params).scaled(scale)
    drawer = get_registry().create("renderer", renderer, {**(renderer_options or {}), "width": camera.width,
                                                         "height": camera.height})
    rows = math.ceil(len(scenes) / columns)
    sheet = Image.new("RGB", (columns * camera.width, rows * camera.height), (255, 255, 255))
    try:
        for k, scene in enumerate(scenes):
            cam = CameraParams.from_scene_params(scene.camera_params).scaled(scale)
            view, data = checks.view_model(models_from_scene(object_set, scene), placements_from_scene(scene), cam,
                                           table_x, table_y)
            drawer.setup(scene, view)
            tile = Image.fromarray(np.asarray(drawer.render(data, checks.CAMERA_NAME).rgb))
            x, y = (k % columns) * camera.width, (k // columns) * camera.height
            sheet.paste(tile, (x, y))
            ImageDraw.Draw(sheet).text((x + 4, y + 4), f"#{scene.image_index}", fill=(255, 255, 255))
    finally:
        drawer.close()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(path)
    return path
