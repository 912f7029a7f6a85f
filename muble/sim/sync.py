"""Reading the scene graph back from MuJoCo: poses, bounding boxes, flags and measured values."""
from __future__ import annotations

import copy

import numpy as np

from muble.core.observation import MEASURED_EXTRA, TOUCHING_TABLE
from muble.core.scene import SceneGraph
from muble.stage.geometry import tilt_deg, world_extents

RAISED_HEIGHT = 0.01  # m above its resting height counts as raised


def object_bbox(env, obj_id: int) -> dict[str, float]:
    """The object's bbox as a scene graph records it: the extents (x, y, z) of its model's bounding box in its own
    frame (``muble.stage.footprint``)."""
    ext = np.asarray(env.object_models[obj_id].extents, dtype=float)
    return {"x": float(ext[0]), "y": float(ext[1]), "z": float(ext[2])}


def world_bbox(env, obj_id: int) -> dict[str, float]:
    """Extents (x, y, z) of the world-axis-aligned box that holds the object's bbox as it stands now
    (``muble.stage.geometry.world_extents``)."""
    bbox = object_bbox(env, obj_id)
    ext = world_extents((bbox["x"], bbox["y"], bbox["z"]), env.object_pose(obj_id).quat)
    return {"x": float(ext[0]), "y": float(ext[1]), "z": float(ext[2])}


def is_raised(env, obj_id: int) -> bool:
    """More than ``RAISED_HEIGHT`` above where the scene put it (its body's initial height)."""
    rest_z = float(env.model.body_pos[env.grasp.body_of[obj_id]][2])
    return bool(env.object_pose(obj_id).pos[2] > rest_z + RAISED_HEIGHT)


LIFT_CLEARANCE = 0.005  # m above the height at which it was grasped that a held object must be to count as lifted


def touches_support(env, obj_id: int, tolerance: float = 0.001) -> bool:
    """The object touches the table or another object (contacts of the live physics, within ``tolerance``)."""
    m, d = env.model, env.data
    body = env.grasp.body_of[obj_id]
    supports = {int(m.geom_bodyid[m.geom(env.names.table_geom).id])}
    supports |= {int(b) for i, b in env.grasp.body_of.items() if i != obj_id}
    for c in d.contact[: d.ncon]:
        if c.dist > tolerance:
            continue
        b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
        if (b1 == body and b2 in supports) or (b2 == body and b1 in supports):
            return True
    return False


def is_lifted(env, obj_id: int) -> bool:
    """Held, clear of every support, and higher than where it was grasped: what weighing needs."""
    if env.held_object != obj_id or touches_support(env, obj_id, tolerance=0.002):
        return False
    grasped_at = env.grasp.grasp_height
    return grasped_at is None or env.object_pose(obj_id).pos[2] > grasped_at + LIFT_CLEARANCE


TOUCH_DISTANCE = 0.001  # m between two geoms that counts as touching
TABLE = TOUCHING_TABLE


def touching(env) -> dict[int, set]:
    """What each object touches now, from the live contacts: other objects' scene ids and ``"table"``."""
    m, d = env.model, env.data
    body_to_id = {int(b): i for i, b in env.grasp.body_of.items()}
    table = int(m.geom_bodyid[m.geom(env.names.table_geom).id])
    out: dict[int, set] = {i: set() for i in env.grasp.body_of}
    for c in d.contact[: d.ncon]:
        if c.dist > TOUCH_DISTANCE:
            continue
        b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
        for a, b in ((b1, b2), (b2, b1)):
            if a in body_to_id:
                if b in body_to_id and b != a:
                    out[body_to_id[a]].add(body_to_id[b])
                elif b == table:
                    out[body_to_id[a]].add(TABLE)
    return out


def scene_graph_from_sim(env, previous: SceneGraph) -> SceneGraph:
    """A copy of ``previous`` with every object's pose, bbox, flags and physical state taken from the simulation
    now: ``extra["touching"]`` (sorted object ids, then ``"table"``), ``extra["tilt_deg"]`` and
    ``extra["speed"]`` (m/s)."""
    scene = copy.deepcopy(previous)
    contacts = touching(env)
    for obj in scene.objects:
        pose = env.object_pose(obj.id)
        obj.position = pose.pos
        obj.orientation = pose.quat
        obj.rotation = float(np.degrees(obj.yaw))
        obj.bbox = object_bbox(env, obj.id)
        in_hand = env.held_object == obj.id
        obj.extra["in_hand"] = in_hand
        obj.extra["raised"] = is_raised(env, obj.id)
        touched = contacts.get(obj.id, set())
        obj.extra["touching"] = sorted(t for t in touched if t != TABLE) + ([TABLE] if TABLE in touched else [])
        obj.extra["tilt_deg"] = round(tilt_deg(pose.quat), 2)
        obj.extra["speed"] = round(float(np.linalg.norm(env.data.cvel[env.grasp.body_of[obj.id]][3:])), 4)
        measured = env.measurements.get(obj.id, {}) if hasattr(env, "measurements") else {}
        if "weight" in measured:
            obj.weight = measured["weight"]
        for name, key in MEASURED_EXTRA.items():
            if name in measured:
                obj.extra[key] = measured[name]
    return scene
