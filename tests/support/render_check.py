"""MuJoCo's own view of a rendered state, what renderer tests and benchmarks compare a renderer's passes with."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import mujoco


def mujoco_reference(model: "mujoco.MjModel", data: "mujoco.MjData", camera: str, width: int, height: int,
                     labels: np.ndarray, groups: tuple[int, ...] = (1,)) -> tuple[np.ndarray, np.ndarray]:
    """Segmentation labels and depth of the same state from MuJoCo's own renderer, drawing ``groups`` only
    (needs a GL context: ``MUJOCO_GL=egl`` headless)."""
    import mujoco

    from muble.core.types import SEG_BACKGROUND

    renderer = mujoco.Renderer(model, height, width)
    try:
        option = mujoco.MjvOption()
        option.geomgroup[:] = 0
        option.sitegroup[:] = 0  # sites (grip markers) are not scenery; Blender draws none
        for group in groups:
            option.geomgroup[group] = 1
        renderer.update_scene(data, camera, scene_option=option)
        renderer.enable_segmentation_rendering()
        seg = renderer.render().copy()
        renderer.disable_segmentation_rendering()
        renderer.enable_depth_rendering()
        depth = renderer.render().copy()
        renderer.disable_depth_rendering()
    finally:
        renderer.close()
    ids, types = seg[..., 0], seg[..., 1]
    ref = np.full(ids.shape, SEG_BACKGROUND, dtype=np.int32)
    hit = (types == mujoco.mjtObj.mjOBJ_GEOM) & (ids >= 0)
    ref[hit] = labels[ids[hit]]
    return ref, depth


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    union = (a | b).sum()
    return float((a & b).sum() / union) if union else 1.0
