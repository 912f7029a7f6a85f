"""Which MuJoCo geoms are drawn, and which segmentation label each one carries.

A geom's label follows from the top-level body it hangs under (its MuJoCo root body): the robot and gripper,
the table, one scene object, or the world itself (floor and walls, which count as background). The same
mapping serves the Blender passes and any comparison with MuJoCo's own segmentation.
"""
from __future__ import annotations

import logging
import re
from typing import TYPE_CHECKING

import numpy as np

from muble.core.types import SEG_BACKGROUND, SEG_ROBOT, SEG_TABLE
from muble.core.object_physics import object_id_from_name

if TYPE_CHECKING:  # pragma: no cover
    import mujoco

    from muble.core.scene import SceneGraph

log = logging.getLogger(__name__)

# Root-body names: robosuite prefixes robots "robot<i>_", grippers "gripper<i>_", mounts "mount<i>_".
_ROBOT_ROOT = re.compile(r"^(robot|gripper|mount)\d*_")
_TABLE_ROOT = re.compile(r"^table")

# Object pass indices of the labels (Blender's pass index is a non-negative integer).
PASS_BACKGROUND, PASS_TABLE, PASS_ROBOT, PASS_FIRST_OBJECT = 0, 1, 2, 3


def body_name(model: "mujoco.MjModel", body: int) -> str:
    import mujoco

    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or ""


def root_label(name: str, object_ids: set[int] | None = None) -> int:
    """The segmentation label of everything under a root body called ``name``."""
    if _ROBOT_ROOT.match(name):
        return SEG_ROBOT
    if _TABLE_ROOT.match(name):
        return SEG_TABLE
    obj_id = object_id_from_name(name)  # the environment's naming convention: "obj<id>" then "_" or the end
    if obj_id is not None:
        if object_ids is None or obj_id in object_ids:
            return obj_id
        log.warning("body '%s' names object %d, which the scene graph lacks; drawn as background", name, obj_id)
    return SEG_BACKGROUND


def geom_labels(model: "mujoco.MjModel", scene: "SceneGraph | None" = None) -> np.ndarray:
    """Segmentation label of every geom, shape (ngeom,), int32."""
    object_ids = set(scene.ids) if scene is not None else None
    root_labels: dict[int, int] = {0: SEG_BACKGROUND}
    labels = np.empty(model.ngeom, dtype=np.int32)
    for geom in range(model.ngeom):
        root = int(model.body_rootid[model.geom_bodyid[geom]])
        if root not in root_labels:
            root_labels[root] = root_label(body_name(model, root), object_ids)
        labels[geom] = root_labels[root]
    return labels


def drawn_geoms(model: "mujoco.MjModel", labels: np.ndarray, groups: list[int] | tuple[int, ...],
                world: bool = True, walls: bool = True) -> np.ndarray:
    """Indices of the geoms a renderer draws: in one of ``groups``, not fully transparent, and part of the
    robot, the table, an object or (when ``world``) the world body: its planes (the floor) and, when
    ``walls``, its other geoms (robosuite's room). Other top-level bodies, such as robosuite's translucent
    end-effector target markers, are left out."""
    import mujoco

    mask = np.isin(model.geom_group, np.asarray(groups)) & (model.geom_rgba[:, 3] > 0)
    on_world = model.geom_bodyid == 0
    if not walls:
        on_world &= model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE
    mask &= (labels != SEG_BACKGROUND) | (on_world if world else False)
    return np.flatnonzero(mask)


def pass_index(label: int) -> int:
    """Blender object pass index that encodes a segmentation label."""
    if label >= 0:
        return PASS_FIRST_OBJECT + label
    return {SEG_BACKGROUND: PASS_BACKGROUND, SEG_TABLE: PASS_TABLE, SEG_ROBOT: PASS_ROBOT}[label]


def labels_from_pass(index: np.ndarray) -> np.ndarray:
    """Segmentation labels from an object-index pass (float or int array)."""
    code = np.rint(index).astype(np.int32)
    seg = code - PASS_FIRST_OBJECT
    seg[code == PASS_BACKGROUND] = SEG_BACKGROUND
    seg[code == PASS_TABLE] = SEG_TABLE
    seg[code == PASS_ROBOT] = SEG_ROBOT
    return seg
