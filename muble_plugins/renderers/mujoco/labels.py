"""Which segmentation label each MuJoCo geom gets, decided from body and geom names.

Objects are bodies named ``obj<id>`` (``muble.sim.object_mjcf``), ``object<id>`` or ``object_<id>`` (the scene
id; child bodies and geoms of that body inherit it). The
table is anything whose body or geom name contains ``table``. The robot is everything robosuite prefixes with
``robot<k>_``, ``gripper<k>_``, ``mount<k>_`` or ``fixed_mount<k>_``. Everything else (floor, walls, world
geoms) is background.
"""
from __future__ import annotations

import re

import numpy as np

from muble import SEG_BACKGROUND, SEG_ROBOT, SEG_TABLE

OBJECT_NAME = re.compile(r"^obj(?:ect)?_?(\d+)(?:$|[_/.])")
ROBOT_NAME = re.compile(r"^(?:robot|gripper|mount|fixed_mount)\d*_")


def _name(model, objtype, index: int) -> str:
    import mujoco

    return mujoco.mj_id2name(model, objtype, index) or ""


def _label_of_names(names: list[str]) -> int | None:
    for name in names:
        match = OBJECT_NAME.match(name)
        if match:
            return int(match.group(1))
    for name in names:
        if ROBOT_NAME.match(name):
            return SEG_ROBOT
    for name in names:
        if "table" in name.lower():
            return SEG_TABLE
    return None


def geom_labels(model) -> np.ndarray:
    """(ngeom,) int32 label of every geom: object id, ``SEG_TABLE``, ``SEG_ROBOT`` or ``SEG_BACKGROUND``."""
    import mujoco

    labels = np.full(model.ngeom, SEG_BACKGROUND, dtype=np.int32)
    body_label: dict[int, int | None] = {}
    for g in range(model.ngeom):
        body = int(model.geom_bodyid[g])
        if body not in body_label:
            chain = []
            b = body
            while b > 0:  # the world body (0) says nothing about what a geom is
                chain.append(_name(model, mujoco.mjtObj.mjOBJ_BODY, b))
                b = int(model.body_parentid[b])
            body_label[body] = _label_of_names(chain)
        own = _label_of_names([_name(model, mujoco.mjtObj.mjOBJ_GEOM, g)])
        label = body_label[body] if body_label[body] is not None else own
        labels[g] = SEG_BACKGROUND if label is None else label
    return labels
