"""The ``move_vel`` primitive: the hand at a constant velocity for a duration; it measures the travel."""
from __future__ import annotations

import numpy as np

from muble import ActionResult, Param, Pose, PoseGoal, PrimitiveAction, get_registry
from muble.core.params import argument
from muble_plugins.primitives import context as ctx
from muble_plugins.primitives import tolerances as tol

# m between the hand's travel and velocity x duration beyond which the motion counts as blocked: 1 cm, over three
# times the 3 mm goal tolerance the straight line is planned to.
MOVE_VEL_TOLERANCE = 0.01


class MoveVel(PrimitiveAction):
    """Move the hand at ``velocity`` (vx, vy, vz in m/s, world frame) for ``duration`` seconds, continuously.

    The motion is a timed straight line (collision-checked like any other move) tracked by the physics loop;
    the measurement is the displacement actually travelled.
    """

    params = (Param("velocity", "vector", required=True, low=-0.5, high=0.5, length=3, doc="m/s, world frame"),
              Param("duration", "number", low=0.0, high=10.0, default=1.0, doc="s"))
    # What ``ActionResult.measurement`` holds (docs/agent_api.md).
    reports = "[dx, dy, dz]: the metres the hand actually travelled, world frame"

    def execute(self, env) -> ActionResult:
        velocity = np.asarray(self.arguments.get("velocity", (0.0, 0.0, 0.0)), dtype=float).reshape(3)
        duration = float(argument(self, "duration"))
        speed = float(np.linalg.norm(velocity))
        start = env.ee_pose()
        if speed * duration < 1e-4:
            env.hold(duration)
            return ActionResult(True, measurement=[0.0, 0.0, 0.0])
        world = env.collision_world()
        line = get_registry().create("planner", "straight_line",
                                     {"speed": speed, "max_distance": speed * duration + 0.01})
        goal = PoseGoal(Pose(start.pos + velocity * duration, start.quat), *tol.VELOCITY)
        report = ctx.execute(env, line.plan(env.arm_q(), goal, world), world, settle=0.1)
        moved = env.ee_pose().pos - start.pos
        off = float(np.linalg.norm(moved - velocity * duration))
        info = {"duration": report.duration, "unintended_contacts": sorted(report.unintended_contacts)}
        if off > MOVE_VEL_TOLERANCE:
            return ActionResult(False, measurement=moved.tolist(), info=info,
                                failure_reason=f"the hand ended {off * 1000:.0f} mm from where the motion should "
                                               "have taken it (blocked)")
        return ActionResult(True, measurement=moved.tolist(), info=info)
