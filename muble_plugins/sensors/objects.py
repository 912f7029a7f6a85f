"""Object state as the simulation has it: poses, world bounding boxes, in-hand and raised flags."""
from __future__ import annotations

from typing import Any

from muble import Sensor


class ObjectState(Sensor):
    def read(self, env) -> dict[str, Any]:
        out = {}
        for obj_id in env.object_ids:
            pose = env.object_pose(obj_id)
            out[obj_id] = {
                "position": pose.pos, "quaternion": pose.quat, "bbox": env.world_bbox(obj_id),
                "in_hand": env.held_object == obj_id, "raised": env.is_raised(obj_id),
            }
        return out
