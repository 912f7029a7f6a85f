"""Object state as the simulation has it: poses, world bounding boxes, in-hand and raised flags."""
from __future__ import annotations

from typing import Any

from muble import Sensor
from muble.sim.sync import RAISED_HEIGHT, world_bbox


class ObjectState(Sensor):
    def read(self, env) -> dict[str, Any]:
        out = {}
        for obj_id in env.grasp.object_ids:
            pose = env.object_pose(obj_id)
            rest_z = float(env.model.body_pos[env.grasp.body_of[obj_id]][2])
            out[obj_id] = {
                "position": pose.pos, "quaternion": pose.quat, "bbox": world_bbox(env, obj_id),
                "in_hand": env.held_object == obj_id, "raised": bool(pose.pos[2] > rest_z + RAISED_HEIGHT),
            }
        return out
