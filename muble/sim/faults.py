"""Physics faults: NaN or runaway states, solver blow-ups and objects that leave the table."""
from __future__ import annotations

import mujoco
import numpy as np

from muble.core.errors import PhysicsError

MAX_SPEED = 50.0  # m/s or rad/s in any degree of freedom: nothing on a tabletop moves this fast
BELOW_TABLE = 0.05  # m: an object whose origin is this far below the table top has fallen off


class FaultDetector:
    def __init__(self, model: mujoco.MjModel, names):
        self.model = model
        self.object_ids = sorted(names.objects)
        self.object_bodies = np.array([model.body(names.objects[i]).id for i in self.object_ids], dtype=int)

    def check(self, data: mujoco.MjData) -> None:
        """Raise ``PhysicsError`` naming the fault; cheap enough to run every control step."""
        if not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
            raise PhysicsError(f"the simulation state became NaN/infinite at t={data.time:.3f} s; reduce the "
                               "timestep, or check the actions and object masses for extreme values")
        speed = np.abs(data.qvel).max(initial=0.0)
        if speed > MAX_SPEED:
            raise PhysicsError(f"the simulation became unstable at t={data.time:.3f} s (a joint moves at "
                               f"{speed:.0f} units/s); reduce the timestep or the controller gains")
        if len(self.object_bodies):
            pos = data.xpos[self.object_bodies]
            # Falling below the table top is the unambiguous sign: an object held out past the edge is fine.
            off = pos[:, 2] < -BELOW_TABLE
            if off.any():
                which = [self.object_ids[i] for i in np.flatnonzero(off)]
                raise PhysicsError(f"object(s) {which} left the table at t={data.time:.3f} s; the scene is broken, "
                                   "reset the environment")
