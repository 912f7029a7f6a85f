"""Physical acceptance checks for object models: drop onto the table, stack on a base, drop into a bowl.

Plugin authors can run these on their own object sets. Each check builds a standalone world with
``muble.sim.object_mjcf.test_world_xml``, simulates real MuJoCo physics and reports what it measured.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from muble.core.objects import ObjectModel
from muble.sim.object_mjcf import object_id_from_name, test_world_xml
from muble.stage.geometry import tilt_deg

UPRIGHT = (1.0, 0.0, 0.0, 0.0)


@dataclass
class RestReport:
    """The state after settling: per object position (m), tilt (deg), speed (m/s), and the deepest contact."""

    positions: np.ndarray  # (n, 3)
    tilt_deg: np.ndarray  # (n,)
    speed: np.ndarray  # (n,) linear speed
    angular_speed: np.ndarray  # (n,) rad/s
    penetration: float  # m, deepest contact penetration (>= 0)
    touching: set[tuple[int, int]]  # contacting pairs of object ids; -1 is the table


def settle(placements: list[tuple[ObjectModel, tuple, tuple]], seconds: float = 2.0) -> RestReport:
    """Simulate ``placements`` (model, pos, quat) on a table for ``seconds`` and report the final state."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(test_world_xml(placements))
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, nstep=int(round(seconds / model.opt.timestep)))
    n = len(placements)
    qpos = data.qpos.reshape(n, 7)
    qvel = data.qvel.reshape(n, 6)
    touching, penetration = set(), 0.0
    for c in data.contact[: data.ncon]:
        penetration = max(penetration, -float(c.dist))
        ids = []
        for geom in (c.geom1, c.geom2):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
            oid = object_id_from_name(name)
            ids.append(-1 if oid is None else oid)
        touching.add(tuple(sorted(ids)))
    return RestReport(qpos[:, :3].copy(), np.array([tilt_deg(q) for q in qpos[:, 3:7]]),
                      np.linalg.norm(qvel[:, :3], axis=1), np.linalg.norm(qvel[:, 3:], axis=1), penetration, touching)


def drop(model: ObjectModel, height: float = 0.05, seconds: float = 2.0) -> RestReport:
    """Free fall of ``model`` upright from ``height`` above the table."""
    return settle([(model, (0.0, 0.0, height), UPRIGHT)], seconds)


def stack(base: ObjectModel, top: ObjectModel, gap: float = 0.005, seconds: float = 2.0) -> RestReport:
    """``top`` released just above ``base``'s highest point, centred on it; object 0 is the base."""
    return settle([(base, (0.0, 0.0, 0.0), UPRIGHT), (top, (0.0, 0.0, float(base.extents[2]) + gap), UPRIGHT)],
                  seconds)
