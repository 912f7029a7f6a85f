"""The grasp model: a weld equality constraint per object, switched on when the pads of all fingers touch that
object and switched off (object at rest) when the gripper opens. ``friction`` mode never welds."""
from __future__ import annotations

import logging

import mujoco
import numpy as np

from muble.sim.jaw_contact import JawContacts, finger_geom_sides

logger = logging.getLogger(__name__)

GRASP_MODES = ("weld", "friction")


class GraspModel:
    def __init__(self, model: mujoco.MjModel, names, mode: str = "weld"):
        self.model = model
        self.mode = mode
        self.hand_body = model.body(names.hand_body).id
        self.object_ids = sorted(names.objects)
        self.body_of = {i: model.body(names.objects[i]).id for i in self.object_ids}
        self.weld_of = {i: model.equality(names.welds[i]).id for i in self.object_ids}
        # geom -> scene object id (-1: not an object), for vectorised contact checks
        self.geom_object = np.full(model.ngeom, -1, dtype=int)
        body_to_obj = {b: i for i, b in self.body_of.items()}
        for g in range(model.ngeom):
            self.geom_object[g] = body_to_obj.get(int(model.geom_bodyid[g]), -1)
        self.pad_side = np.zeros(model.ngeom, dtype=int)  # 1 left pad, 2 right pad
        self.pad_side[[model.geom(n).id for n in names.left_pads]] = 1
        self.pad_side[[model.geom(n).id for n in names.right_pads]] = 2
        self.held: int | None = None
        self.grasp_height: float | None = None  # z of the held object's origin when it was grasped
        # The jaw contact law (see muble.sim.jaw_contact): jaws feel each object as one spring of its stiffness.
        self.jaws = JawContacts(model, finger_geom_sides(model, {1: list(names.left_pads), 2: list(names.right_pads)},
                                                         list(names.gripper_joints)),
                                self.geom_object, self.body_of, self.pad_side)
        # geom -> 1 finger (jaw or pad), 2 object, 0 other: a contact between a finger and an object is the only
        # pair whose codes sum to 3, so one gather and one sum tell whether any finger touches any object.
        self._contact_code = np.zeros(model.ngeom, dtype=np.int8)
        self._contact_code[self.geom_object >= 0] = 2
        self._contact_code[(self.jaws.jaw_side > 0) | (self.pad_side > 0)] = 1

    def touching(self, data: mujoco.MjData) -> dict[int, int]:
        """Scene id -> bit mask of finger sides (1 left, 2 right) whose pads touch that object now."""
        n = data.ncon
        if n == 0:
            return {}
        g1 = data.contact.geom1[:n]
        g2 = data.contact.geom2[:n]
        out: dict[int, int] = {}
        for a, b in ((g1, g2), (g2, g1)):
            side = self.pad_side[a]
            obj = self.geom_object[b]
            hit = (side > 0) & (obj >= 0)
            for s, o in zip(side[hit], obj[hit]):
                out[int(o)] = out.get(int(o), 0) | int(s)
        return out

    def fingers_touch_objects(self, data: mujoco.MjData) -> bool:
        """Whether any finger geom touches any object geom now (the cheap test run every control step)."""
        n = data.ncon
        return bool(n) and bool((self._contact_code[data.contact.geom[:n]].sum(axis=1) == 3).any())

    def update(self, data: mujoco.MjData, closing: bool) -> None:
        """Rescale jaw contacts; attach when closing and all pads touch one object; release when the gripper opens."""
        touch = self.fingers_touch_objects(data)
        # With no finger on any object and no object rescaled, the jaw law has nothing to do.
        if touch or self.jaws.scaled:
            self.jaws.update(data)
        if self.mode != "weld":
            return
        if self.held is not None and not closing:
            self.release(data)
        elif self.held is None and closing and touch:
            for obj, sides in self.touching(data).items():
                if sides == 3:
                    self.attach(data, obj)
                    break

    def attach(self, data: mujoco.MjData, obj: int) -> None:
        """Weld ``obj`` to the hand at their current relative pose (no jump)."""
        hand, body = self.hand_body, self.body_of[obj]
        # relpose = pose of body2 (object) in the frame of body1 (hand)
        hand_quat_inv = np.empty(4)
        mujoco.mju_negQuat(hand_quat_inv, data.xquat[hand])
        rel_pos = np.empty(3)
        mujoco.mju_rotVecQuat(rel_pos, data.xpos[body] - data.xpos[hand], hand_quat_inv)
        rel_quat = np.empty(4)
        mujoco.mju_mulQuat(rel_quat, hand_quat_inv, data.xquat[body])
        eq = self.weld_of[obj]
        self.model.eq_data[eq, 0:3] = 0.0
        self.model.eq_data[eq, 3:6] = rel_pos
        self.model.eq_data[eq, 6:10] = rel_quat
        self.model.eq_data[eq, 10] = 1.0  # torque scale
        data.eq_active[eq] = 1
        self.held = obj
        self.grasp_height = float(data.xpos[body][2])
        logger.debug("grasped object %d", obj)

    def release(self, data: mujoco.MjData) -> None:
        """Switch the weld off; the object starts from rest."""
        if self.held is None:
            return
        obj = self.held
        data.eq_active[self.weld_of[obj]] = 0
        jnt = self.model.body_jntadr[self.body_of[obj]]
        dof = self.model.jnt_dofadr[jnt]
        data.qvel[dof:dof + 6] = 0.0
        self.held = None
        self.grasp_height = None
        logger.debug("released object %d", obj)
