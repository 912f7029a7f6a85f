"""Physics faults: NaN or runaway states, solver blow-ups and objects that leave the table."""
from __future__ import annotations

import math

import mujoco
import numpy as np

from muble.core.errors import PhysicsError
from muble.stage.table import BELOW_TABLE

MAX_SPEED = 50.0  # m/s or rad/s in any degree of freedom: nothing on a tabletop moves this fast


class FaultDetector:
    def __init__(self, model: mujoco.MjModel, names):
        self.model = model
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
        qvel = data.qvel
        if not (qvel @ qvel <= MAX_SPEED * MAX_SPEED and math.isfinite(data.qpos.sum())):
            self._check_state(data)
        if len(self.object_bodies) and data.xpos[self._bodies, 2].min() < -BELOW_TABLE:
            pos = data.xpos[self.object_bodies]
            # Falling below the table top is the unambiguous sign: an object held out past the edge is fine.
            which = [self.object_ids[i] for i in np.flatnonzero(pos[:, 2] < -BELOW_TABLE)]
            raise PhysicsError(f"object(s) {which} left the table at t={data.time:.3f} s; the scene is broken, "
                               "reset the environment")

    @staticmethod
    def _check_state(data: mujoco.MjData) -> None:
        if not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
            raise PhysicsError(f"the simulation state became NaN/infinite at t={data.time:.3f} s; reduce the "
                               "timestep, or check the actions and object masses for extreme values")
        speed = np.abs(data.qvel).max(initial=0.0)
        if speed > MAX_SPEED:
            raise PhysicsError(f"the simulation became unstable at t={data.time:.3f} s (a joint moves at "
                               f"{speed:.0f} units/s); reduce the timestep or the controller gains")
