"""Camera parameters shared by MuJoCo and Blender: intrinsics, extrinsics and the convention between them.

SHOP-VRB2 scene files store the task camera as Blender does: ``position`` (metres) and ``rotation`` as Euler
angles in degrees with ``rotation_mode`` ``"EulerXYZ"`` (rotate about x, then y, then z, all about world axes,
so the rotation matrix is ``Rz @ Ry @ Rx``). The original release does not store the lens; its ``pixel_coords``
fit a 26 mm lens on Blender's default 36 mm sensor at 848 x 480 (focal length 612 px), the defaults here.

Both Blender and MuJoCo cameras look down their local -Z axis with +Y up and +X to the right of the image, so the
camera-to-world rotation is the same matrix in both; only the way the field of view is given differs. MuJoCo
takes the vertical field of view (``fovy``, degrees) with square pixels; Blender takes the focal length and the
sensor width, fitted to the larger image side (``sensor_fit = 'AUTO'``). Both map a camera-frame point
(x, y, z), z < 0, to pixel u = W/2 + f x / -z, v = H/2 - f y / -z, with f in pixels.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from muble.core.errors import ConfigError

DEFAULT_POSITION = (1.1496347188949585, -0.1398545801639557, 0.22131800651550293)
DEFAULT_ROTATION_DEG = (83.0, 0.0, 89.0)
DEFAULT_WIDTH = 848
DEFAULT_HEIGHT = 480
DEFAULT_LENS_MM = 26.0
DEFAULT_SENSOR_MM = 36.0


def euler_xyz_to_matrix(angles_deg: tuple[float, float, float] | np.ndarray) -> np.ndarray:
    """Blender ``EulerXYZ`` angles (degrees) to a 3x3 rotation matrix (``Rz @ Ry @ Rx``)."""
    return Rotation.from_euler("xyz", np.asarray(angles_deg, dtype=float), degrees=True).as_matrix()


def matrix_to_euler_xyz(rotation: np.ndarray) -> np.ndarray:
    """Inverse of ``euler_xyz_to_matrix`` (degrees; y in [-90, 90])."""
    return Rotation.from_matrix(np.asarray(rotation, dtype=float)).as_euler("xyz", degrees=True)


def matrix_to_quat(rotation: np.ndarray) -> np.ndarray:
    """Rotation matrix to a unit quaternion (w, x, y, z) with w >= 0."""
    quat = Rotation.from_matrix(np.asarray(rotation, dtype=float)).as_quat(scalar_first=True)
    return -quat if quat[0] < 0 else quat


@dataclass
class CameraParams:
    """A pinhole camera: pose in the world (camera looks down -Z, +Y up) and image size and lens."""

    position: np.ndarray = field(default_factory=lambda: np.array(DEFAULT_POSITION))
    rotation: np.ndarray = field(default_factory=lambda: euler_xyz_to_matrix(DEFAULT_ROTATION_DEG))  # cam->world
    width: int = DEFAULT_WIDTH
    height: int = DEFAULT_HEIGHT
    lens_mm: float = DEFAULT_LENS_MM
    sensor_width_mm: float = DEFAULT_SENSOR_MM  # fitted to the larger image side, as Blender's AUTO fit

    def __post_init__(self) -> None:
        self.position = np.asarray(self.position, dtype=float).reshape(3)
        self.rotation = np.asarray(self.rotation, dtype=float).reshape(3, 3)
        if self.width <= 0 or self.height <= 0 or self.lens_mm <= 0 or self.sensor_width_mm <= 0:
            raise ConfigError(
                f"camera needs positive width, height, lens and sensor; got {self.width}x{self.height}, "
                f"lens {self.lens_mm} mm, sensor {self.sensor_width_mm} mm")

    # --- intrinsics -------------------------------------------------------------------------------------------
    @property
    def focal_px(self) -> float:
        return self.lens_mm / self.sensor_width_mm * max(self.width, self.height)

    @property
    def fovy_deg(self) -> float:
        """MuJoCo's vertical field of view in degrees."""
        return math.degrees(2.0 * math.atan(self.height / 2.0 / self.focal_px))

    @property
    def intrinsics(self) -> np.ndarray:
        """3x3 matrix K in the OpenCV convention (x right, y down, z forward)."""
        f = self.focal_px
        return np.array([[f, 0.0, self.width / 2.0], [0.0, f, self.height / 2.0], [0.0, 0.0, 1.0]])

    def scaled(self, factor: float) -> "CameraParams":
        """The same camera at ``factor`` times the resolution (same field of view)."""
        return CameraParams(self.position, self.rotation, max(1, round(self.width * factor)),
                            max(1, round(self.height * factor)), self.lens_mm, self.sensor_width_mm)

    # --- extrinsics -------------------------------------------------------------------------------------------
    @property
    def euler_xyz_deg(self) -> np.ndarray:
        return matrix_to_euler_xyz(self.rotation)

    @property
    def mujoco_quat(self) -> np.ndarray:
        """Orientation for a MuJoCo ``<camera quat=...>``: the same matrix, MuJoCo also looks down -Z."""
        return matrix_to_quat(self.rotation)

    def world_to_camera(self, points: np.ndarray) -> np.ndarray:
        """Points (N, 3) in the camera frame (z < 0 in front of the camera).

        Each coordinate is summed in a fixed order with elementwise products, not by a BLAS product, whose
        result's last bits depend on the kernel the CPU gets: what is computed here is written to scene files
        and must be the same on every machine (docs/protocol.md, "The same on every CPU")."""
        d = np.atleast_2d(np.asarray(points, dtype=float)) - np.asarray(self.position, dtype=float)
        r = np.asarray(self.rotation, dtype=float)
        return np.stack([(d[:, 0] * r[0, j] + d[:, 1] * r[1, j]) + d[:, 2] * r[2, j] for j in range(3)], axis=1)

    def project(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) world points to (N, 3) rows of pixel u, pixel v (from the top left) and depth along the view."""
        pc = self.world_to_camera(np.atleast_2d(points))
        depth = -pc[:, 2]
        f = self.focal_px
        with np.errstate(divide="ignore", invalid="ignore"):
            u = self.width / 2.0 + f * pc[:, 0] / depth
            v = self.height / 2.0 - f * pc[:, 1] / depth
        return np.stack([u, v, depth], axis=1)

    # --- SHOP-VRB2 files --------------------------------------------------------------------------------------
    @classmethod
    def from_scene_params(cls, params: dict[str, Any] | None, **image: Any) -> "CameraParams":
        """From a scene file's ``camera_params`` (Blender EulerXYZ degrees); ``image`` sets width/height/lens."""
        if not params:
            return cls(**image)
        mode = params.get("rotation_mode", "EulerXYZ")
        if mode != "EulerXYZ":
            raise ConfigError(f"camera rotation_mode '{mode}' is not supported; valid rotation_mode names: EulerXYZ")
        extra: dict[str, Any] = {k: params[k] for k in ("width", "height", "lens_mm", "sensor_width_mm")
                                 if k in params}
        extra.update(image)
        return cls(np.array(params["position"], dtype=float), euler_xyz_to_matrix(params["rotation"]), **extra)

    def to_scene_params(self) -> dict[str, Any]:
        """The scene file's ``camera_params`` block (the original three keys plus image size and lens)."""
        return {
            "position": [float(v) for v in self.position],
            "rotation": [float(v) for v in self.euler_xyz_deg],
            "rotation_mode": "EulerXYZ",
            "width": int(self.width),
            "height": int(self.height),
            "lens_mm": float(self.lens_mm),
            "sensor_width_mm": float(self.sensor_width_mm),
        }
