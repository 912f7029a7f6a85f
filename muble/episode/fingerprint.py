"""Episode fingerprints: the physical world after every primitive, rounded to a stated tolerance, so that two runs
of an episode (two machines, two BLAS kernels, two executors) can be told to agree or not, and where they part.

A fingerprint holds every object's position (units of ``POSITION_UNIT``, 0.1 mm) and orientation (its rotation
vector in units of ``ANGLE_UNIT``, 0.1 degree), the arm's joint angles (0.1 degree), the pads' opening (0.1 mm) and
the held object. Two fingerprints agree when no value differs by more than ``TOLERANCE`` units (a value that sits
on a rounding boundary may round either way on two machines that differ in the last bit). ``platform`` says what
computed them: MuJoCo's version, numpy's, the BLAS kernel OpenBLAS chose and numpy's SIMD level.
"""
from __future__ import annotations

import functools
import hashlib
import json
import os
from typing import Any

import numpy as np

POSITION_UNIT = 1e-4  # m (0.1 mm)
ANGLE_UNIT = 0.1  # degrees
TOLERANCE = 1  # units a value may differ by and still agree


def _rotation_degrees(quat: np.ndarray) -> np.ndarray:
    """The rotation vector (axis times angle, degrees) of a unit quaternion (w, x, y, z), the short way round."""
    q = np.asarray(quat, dtype=float)
    q = q / np.linalg.norm(q)
    if q[0] < 0:
        q = -q
    s = float(np.linalg.norm(q[1:]))
    if s < 1e-12:
        return np.zeros(3)
    angle = 2.0 * np.arctan2(s, q[0])
    return np.degrees(angle) * q[1:] / s


def fingerprint(env: Any) -> dict[str, Any]:
    """The world's fingerprint now (see the module's doc)."""
    objects = {}
    for i in sorted(env.object_ids):
        pose = env.object_pose(i)
        objects[str(i)] = [int(v) for v in np.rint(np.asarray(pose.pos) / POSITION_UNIT)] + \
                          [int(v) for v in np.rint(_rotation_degrees(pose.quat) / ANGLE_UNIT)]
    return {"objects": objects,
            "arm": [int(v) for v in np.rint(np.degrees(env.arm_q()) / ANGLE_UNIT)],
            "gripper": int(np.rint(env.gripper_opening() / POSITION_UNIT)),
            "held": env.held_object}


def digest(fingerprints: list[dict[str, Any]]) -> str:
    """A short digest of a list of fingerprints (equal digests: identical to the unit)."""
    return hashlib.sha256(json.dumps(fingerprints, sort_keys=True).encode()).hexdigest()[:16]


def difference(a: dict[str, Any], b: dict[str, Any]) -> int:
    """The largest difference in units between two fingerprints; a changed held object or a missing object counts
    as a difference larger than any tolerance."""
    if a.get("held") != b.get("held") or set(a["objects"]) != set(b["objects"]) or len(a["arm"]) != len(b["arm"]):
        return 10**9
    worst = abs(int(a["gripper"]) - int(b["gripper"]))
    worst = max(worst, max((abs(x - y) for x, y in zip(a["arm"], b["arm"])), default=0))
    for key, values in a["objects"].items():
        worst = max(worst, max(abs(x - y) for x, y in zip(values, b["objects"][key])))
    return int(worst)


def first_difference(a: list[dict[str, Any]], b: list[dict[str, Any]], tolerance: int = TOLERANCE
                     ) -> tuple[int | None, int]:
    """(index of the first fingerprint that differs by more than ``tolerance`` units, or None; the largest
    difference over the fingerprints both lists have). A list that ends early differs where it ends."""
    first, worst = None, 0
    for i, (x, y) in enumerate(zip(a, b)):
        d = difference(x, y)
        worst = max(worst, d)
        if first is None and d > tolerance:
            first = i
    if first is None and len(a) != len(b):
        first = min(len(a), len(b))
    return first, worst


def platform() -> dict[str, Any]:
    """What computed an episode's physics: MuJoCo's and numpy's versions, OpenBLAS's kernel (and the variable that
    chose it) and numpy's SIMD dispatch. Read once per process (``_platform``) and copied for each record."""
    return dict(_platform())


@functools.cache
def _platform() -> dict[str, Any]:
    import mujoco

    info: dict[str, Any] = {"mujoco": mujoco.__version__, "numpy": np.__version__,
                            "openblas_coretype": os.environ.get("OPENBLAS_CORETYPE"),
                            "npy_disable_cpu_features": os.environ.get("NPY_DISABLE_CPU_FEATURES")}
    try:
        from threadpoolctl import threadpool_info

        # numpy's and scipy's OpenBLAS each choose a kernel; both named, in a fixed order.
        kernels = sorted({str(p.get("architecture")) for p in threadpool_info() if p.get("internal_api") == "openblas"})
        if kernels:
            info["blas_kernel"] = "+".join(kernels)
    except ImportError:  # pragma: no cover - threadpoolctl comes with scipy/scikit-learn stacks
        pass
    try:
        from numpy._core._multiarray_umath import __cpu_features__

        wide = [f for f in ("AVX512_SKX", "AVX512F", "AVX2", "FMA3", "SSE42") if __cpu_features__.get(f)]
        info["numpy_simd"] = wide[0] if wide else "baseline"
    except ImportError:  # pragma: no cover - numpy < 2
        pass
    return info
