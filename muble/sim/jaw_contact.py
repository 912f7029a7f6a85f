"""The jaw contact law: while fingers touch an object, the object presses back on the jaws as one linear spring.

MuJoCo splits a contact into points, each a spring of ``k / ((1-d)·A_i)`` at rest (``k`` = -solref[0] of the
object's geoms, ``d`` the constant impedance, ``A_i`` the summed ``body_invweight0`` of the two bodies). A flat
pad on a flat face gives 4 points, on a faceted cylinder 1, and the finger body's geoms add more as the jaw
closes, so the force per metre of jaw travel would depend on the collision geometry rather than the object.

``JawContacts.update`` (once per control step) rescales ``k`` of each touched object so that

    sum over both jaws of  f_i · cos_i  =  K · (penetration of the left jaw + of the right jaw),

with ``K`` the object's ground-truth stiffness recovered from its base solref (``object_mjcf``), ``cos_i`` the
cosine between point i's normal (finger to object) and its jaw's closing direction (from the jaw's pad centre
towards the other jaw's), and a jaw's penetration ``depth_i / cos_i`` at its deepest point among those with
``cos_i >= SQUARE``: how far it has advanced into the object along its closing. A mesh object is a union of
convex pieces; a wide pad also grazes the pieces beside the one it faces, and MuJoCo separates those along the
piece's own shortest way out, often across the pad. Counted at full force and depth they made a ceramic mug read
-49 to +40 % with the Robotiq 85 (docs/environment.md, "Stiffness"). The rule is
invariant to scaling all depths, so with the jaw forces held constant it settles in one control step; at rest it
is exact. Objects no finger touches get their base solref back. ``b`` is scaled with ``k``: the jaw keeps the
relaxation time ``b/k`` of the base law (a spring-damper whose time constant does not depend on how many points
MuJoCo splits it into); keeping the damping *ratio* instead would make a jaw of n points sqrt(n) times slower.
Side effect, documented: while a finger touches an object, that object's other contacts (table, other objects)
use the rescaled ``k`` too, since MuJoCo has one solref per geom.
"""
from __future__ import annotations

import logging

import mujoco
import numpy as np

from muble.core.object_physics import JAW_SQUARE
from muble.sim.object_mjcf import CONTACT_IMPEDANCE, MAX_ACCEL_STIFFNESS, stiffness_of_solref

logger = logging.getLogger(__name__)

# A contact sets its jaw's penetration only if its normal is within 60 degrees of the jaw's closing direction
# (shared with squeezing, which reads the jaw's travel where the law presses).
SQUARE = JAW_SQUARE


def finger_geom_sides(model: mujoco.MjModel, pad_geoms_by_side: dict[int, list[str]],
                      finger_joints: list[str]) -> np.ndarray:
    """geom -> jaw side (0 none, else the side key of ``pad_geoms_by_side``): every colliding geom of the finger
    body that carries a pad, and of that body's subtree. The finger body is the body of a gripper joint that is an
    ancestor of (or is) the pad's body."""
    side_of_geom = np.zeros(model.ngeom, dtype=int)
    joint_bodies = {int(model.jnt_bodyid[model.joint(j).id]) for j in finger_joints}

    def ancestors(body: int) -> list[int]:
        chain = [body]
        while body > 0:
            body = int(model.body_parentid[body])
            chain.append(body)
        return chain

    for side, pads in pad_geoms_by_side.items():
        roots = set()
        for pad in pads:
            chain = ancestors(int(model.geom_bodyid[model.geom(pad).id]))
            root = next((b for b in chain if b in joint_bodies), chain[0])
            roots.add(root)
        for g in range(model.ngeom):
            if not (model.geom_contype[g] or model.geom_conaffinity[g]):
                continue
            if roots & set(ancestors(int(model.geom_bodyid[g]))):
                side_of_geom[g] = side
    return side_of_geom


class JawContacts:
    """Per-control-step rescaling of touched objects' contact ``k`` (see module docstring)."""

    def __init__(self, model: mujoco.MjModel, jaw_side: np.ndarray, geom_object: np.ndarray,
                 body_of: dict[int, int], pad_side: np.ndarray | None = None):
        self.model = model
        self.jaw_side = jaw_side
        # geom -> 1 or 2 for the pads (the side keys of jaw_side): their centres give each jaw's closing direction
        self.pad_side = pad_side
        self.geom_object = geom_object
        self.base_solref = model.geom_solref.copy()
        self.invweight = model.body_invweight0[:, 0].copy()
        self.geoms_of: dict[int, np.ndarray] = {}
        self.stiffness: dict[int, float] = {}  # ground truth K (N/m), from the base solref
        self.relaxation: dict[int, float] = {}  # b/k of the base solref, s
        for obj, body in body_of.items():
            geoms = np.flatnonzero((geom_object == obj) & ((model.geom_contype > 0) | (model.geom_conaffinity > 0)))
            direct = [g for g in geoms if self.base_solref[g, 0] < 0]
            if not direct:
                continue  # not an object built by object_mjcf: leave its contacts alone
            k, b = -self.base_solref[direct[0]]
            self.geoms_of[obj] = np.array(direct)
            self.stiffness[obj] = stiffness_of_solref(k, float(model.body_mass[body]))
            self.relaxation[obj] = b / k
        self.scaled: set[int] = set()

    def reset(self) -> None:
        """Every object back to its base solref."""
        for obj in self.scaled:
            self.model.geom_solref[self.geoms_of[obj]] = self.base_solref[self.geoms_of[obj]]
        self.scaled = set()

    def closing_axes(self, data: mujoco.MjData) -> dict[int, np.ndarray] | None:
        """Side -> unit vector in which that jaw closes: from its pads' centre towards the other side's."""
        if self.pad_side is None:
            return None
        centres = {s: data.geom_xpos[self.pad_side == s].mean(axis=0) for s in (1, 2) if np.any(self.pad_side == s)}
        if len(centres) != 2:
            return None
        gap = centres[2] - centres[1]
        length = float(np.linalg.norm(gap))
        return None if length <= 0 else {1: gap / length, 2: -gap / length}

    def update(self, data: mujoco.MjData) -> None:
        n = data.ncon
        touched: dict[int, list] = {}
        if n:
            contact = data.contact
            g1, g2 = contact.geom1[:n], contact.geom2[:n]
            depth = np.maximum(-contact.dist[:n], 0.0)
            normal = contact.frame[:n, :3]  # from geom1 to geom2
            live = contact.exclude[:n] == 0
            inv_mass = self.invweight[self.model.geom_bodyid[g1]] + self.invweight[self.model.geom_bodyid[g2]]
            axes = self.closing_axes(data)
            for a, b, sign in ((g1, g2, 1.0), (g2, g1, -1.0)):
                side = self.jaw_side[a]
                obj = self.geom_object[b]
                hit = np.flatnonzero(live & (side > 0) & (obj >= 0))
                for i in hit:
                    o = int(obj[i])
                    if o in self.geoms_of:
                        s = int(side[i])
                        # how squarely the finger presses there: the cosine between the normal (finger to object)
                        # and the jaw's closing direction
                        cos = 1.0 if axes is None else float(np.clip(sign * normal[i] @ axes[s], 0.0, 1.0))
                        touched.setdefault(o, []).append((s, depth[i], depth[i] / inv_mass[i], cos))
        for obj in self.scaled - set(touched):
            self.model.geom_solref[self.geoms_of[obj]] = self.base_solref[self.geoms_of[obj]]
        self.scaled = set()
        for obj, rows in touched.items():
            sides = np.array([r[0] for r in rows])
            depths = np.array([r[1] for r in rows])
            cos = np.array([r[3] for r in rows])
            # each point presses the jaw, along its closing direction, with k/(1-d) · depth_i/A_i · cos_i
            compliance = float(sum(r[2] * r[3] for r in rows))
            # each jaw's penetration along its closing direction: depth_i / cos_i at its deepest point among those
            # that face it (cos >= SQUARE); a point where the finger grazes the side of a convex piece of a mesh
            # (normal across the closing direction) neither sets the depth nor counts in the force
            axial = np.where(cos >= SQUARE, depths / np.maximum(cos, SQUARE), 0.0)
            deepest = sum(float(axial[sides == s].max()) for s in np.unique(sides))
            if compliance <= 0.0 or deepest <= 0.0:
                continue
            # sum_i f_i·cos_i = k/(1-d) · sum_i depth_i·cos_i/A_i  must equal  K · deepest
            k = self.stiffness[obj] * (1.0 - CONTACT_IMPEDANCE) * deepest / compliance
            if k > MAX_ACCEL_STIFFNESS:
                logger.debug("object %d: jaw stiffness capped (k %.0f > %.0f)", obj, k, MAX_ACCEL_STIFFNESS)
                k = MAX_ACCEL_STIFFNESS
            b = self.relaxation[obj] * k
            self.model.geom_solref[self.geoms_of[obj]] = (-k, -b)
            self.scaled.add(obj)
