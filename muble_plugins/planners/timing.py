"""Time parameterisation of joint-space paths: a trapezoidal velocity profile on every straight segment.

Each segment starts and ends at rest, so the executed motion follows exactly the straight joint-space segments
that the planner checked for collisions (a blended spline would cut corners the checker never saw).
"""
from __future__ import annotations

import numpy as np

from muble.core.types import Trajectory


def _segment_duration(distance: float, max_velocity: float, max_acceleration: float) -> float:
    if distance <= 0.0:
        return 0.0
    if distance < max_velocity**2 / max_acceleration:  # never reaches cruise speed: triangular profile
        return 2.0 * np.sqrt(distance / max_acceleration)
    return distance / max_velocity + max_velocity / max_acceleration


def _progress(t: np.ndarray, duration: float, distance: float, max_velocity: float, max_acceleration: float):
    """Fraction of the segment covered at times ``t`` (0..duration) under the trapezoidal profile."""
    if distance <= 0.0:
        return np.ones_like(t)
    v_peak = min(max_velocity, np.sqrt(distance * max_acceleration))
    t_acc = v_peak / max_acceleration
    s = np.where(
        t < t_acc,
        0.5 * max_acceleration * t**2,
        np.where(
            t <= duration - t_acc,
            0.5 * max_acceleration * t_acc**2 + v_peak * (t - t_acc),
            distance - 0.5 * max_acceleration * (duration - t) ** 2,
        ),
    )
    return np.clip(s / distance, 0.0, 1.0)


def time_parameterise(
    waypoints: np.ndarray,
    max_velocity: float | np.ndarray,
    max_acceleration: float | np.ndarray,
    sample_period: float = 0.02,
    joint_names: tuple[str, ...] = (),
) -> Trajectory:
    """A trajectory through ``waypoints`` (N, dof) with every joint inside its velocity/acceleration limits.

    Limits may be scalars or per joint. The slowest joint of a segment sets its duration; the others are
    scaled to arrive together. The result is sampled every ``sample_period`` seconds plus every waypoint.
    """
    waypoints = np.atleast_2d(np.asarray(waypoints, dtype=float))
    dof = waypoints.shape[1]
    vmax = np.broadcast_to(np.asarray(max_velocity, dtype=float), (dof,))
    amax = np.broadcast_to(np.asarray(max_acceleration, dtype=float), (dof,))
    qs, ts = [waypoints[0]], [0.0]
    for a, b in zip(waypoints[:-1], waypoints[1:]):
        delta = b - a
        durations = [_segment_duration(abs(d), v, ac) for d, v, ac in zip(delta, vmax, amax)]
        k = int(np.argmax(durations))
        duration = durations[k]
        if duration <= 1e-9:
            continue
        n = max(1, int(np.ceil(duration / sample_period)))
        t = np.linspace(0.0, duration, n + 1)[1:]
        frac = _progress(t, duration, abs(delta[k]), vmax[k], amax[k])
        start_time = ts[-1]
        qs.extend(a + f * delta for f in frac)
        ts.extend(start_time + t)
    if len(qs) == 1:  # start equals goal: a single-point trajectory
        return Trajectory(np.array(qs), np.array([0.0]), joint_names)
    return Trajectory(np.array(qs), np.array(ts), joint_names)
