"""Physics faults: NaN or runaway states, solver blow-ups and objects that leave the table."""
from __future__ import annotations

import math

import mujoco
import numpy as np

from muble.core.errors import PhysicsError
from muble.stage.table import BELOW_TABLE

MAX_SPEED = 50.0  # m/s or rad/s in any degree of freedom: nothing on a tabletop moves this fast
# A small ball (a container's loose contents) spins at its surface speed over its radius: a 1 cm ball knocked about
# in a can that falls over turns at 100 rad/s and more. Its turning is held to MAX_SPEED at its surface instead.


def speed_scales(model: mujoco.MjModel) -> np.ndarray:
    """Per degree of freedom, the factor a speed is multiplied by before it is held to ``MAX_SPEED``: 1, but the
    radius (m) for the turning of a free body whose geoms are all spheres (loose contents)."""
    scale = np.ones(model.nv)
    for j in np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE):
        body = model.jnt_bodyid[j]
        geoms = np.flatnonzero(model.geom_bodyid == body)
        if len(geoms) and np.all(model.geom_type[geoms] == mujoco.mjtGeom.mjGEOM_SPHERE):
            adr = model.jnt_dofadr[j]
            scale[adr + 3:adr + 6] = float(model.geom_size[geoms, 0].max())
    return scale


class FaultDetector:
    def __init__(self, model: mujoco.MjModel, names):
        self.model = model
        self.scale = speed_scales(model)
        self._scaled = not np.all(self.scale == 1.0)
        self.object_ids = sorted(names.objects)
        self.object_bodies = np.array([model.body(names.objects[i]).id for i in self.object_ids], dtype=int)
        # Object bodies are usually consecutive: a slice reads their heights without a gather.
        b = self.object_bodies
        contiguous = len(b) > 0 and np.array_equal(b, np.arange(b[0], b[0] + len(b)))
        self._bodies = slice(int(b[0]), int(b[0]) + len(b)) if contiguous else b

    def check(self, data: mujoco.MjData) -> None:
        """Raise ``PhysicsError`` naming the fault; cheap enough to run every control step.

        Runs every control step, so the healthy case is decided by three reductions: ``qvel·qvel <= MAX_SPEED²``
        holds only if every speed is finite and at most ``MAX_SPEED``, a finite ``sum(qpos)`` only if every
        position is finite. Anything else goes through the precise checks below, which name the fault.
        """
        qvel = data.qvel * self.scale if self._scaled else data.qvel
        if not (qvel @ qvel <= MAX_SPEED * MAX_SPEED and math.isfinite(data.qpos.sum())):
            self._check_state(data, self.scale)
        if len(self.object_bodies) and data.xpos[self._bodies, 2].min() < -BELOW_TABLE:
            pos = data.xpos[self.object_bodies]
            # Falling below the table top is the unambiguous sign: an object held out past the edge is fine.
            which = [self.object_ids[i] for i in np.flatnonzero(pos[:, 2] < -BELOW_TABLE)]
            raise PhysicsError(f"object(s) {which} left the table at t={data.time:.3f} s; the scene is broken, "
                               "reset the environment")

    @staticmethod
    def _check_state(data: mujoco.MjData, scale: np.ndarray | float = 1.0) -> None:
        if not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
            raise PhysicsError(f"the simulation state became NaN/infinite at t={data.time:.3f} s; reduce the "
                               "timestep, or check the actions and object masses for extreme values")
        speed = np.abs(data.qvel * scale).max(initial=0.0)
        if speed > MAX_SPEED:
            raise PhysicsError(f"the simulation became unstable at t={data.time:.3f} s (a joint moves at "
                               f"{speed:.0f} units/s); reduce the timestep or the controller gains")
