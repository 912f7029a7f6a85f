"""Where a scene's camera and lamps stand: the generator's defaults, or those moved per scene by the held-out
options ``camera_jitter_m``, ``camera_jitter_deg`` and ``lamp_jitter`` (as CLEVR jitters its camera and lamps).

Each jitter is drawn from a named stream of its own (``scene.camera_jitter``, ``scene.lamp_jitter``:
``muble.core.streams``), which the object and placement streams never meet, so turning jitter on moves the camera
or lamps and nothing else of the scene. It depends on the index, not on the scene sample, so an index keeps one camera and one light whichever sample suits its template, and the
viewpoint is never selected by what the template accepts.
"""
from __future__ import annotations

import numpy as np

from muble.stage.camera import CameraParams, euler_xyz_to_matrix

# Key, back and fill lamps (metres, robot frame) that the Blender renderer lights the table with.
LAMPS = {"Lamp_Key": [3.2, -2.1, 2.2], "Lamp_Back": [-1.8, 2.0, 2.3], "Lamp_Fill": [-2.4, -3.0, 2.5]}

# The least energy factor a lamp gets, whatever ``lamp_jitter`` asks: a lamp dims but never goes out or turns
# negative, so every scene keeps its key, fill and back light.
MIN_LAMP_ENERGY = 0.05


def jittered_camera(camera: CameraParams, rotation_deg, rng: np.random.Generator, metres: float,
                    degrees: float) -> CameraParams:
    """``camera`` moved by a uniform offset in [-metres, metres] on each axis and turned by [-degrees, degrees]
    on each of its Blender ``EulerXYZ`` angles (``rotation_deg``, the angles it was made from); image and lens
    unchanged. Position offsets are drawn before the angles, so either amount leaves the other's draws alone."""
    offset = rng.uniform(-metres, metres, size=3)
    turn = rng.uniform(-degrees, degrees, size=3)
    return CameraParams(camera.position + offset, euler_xyz_to_matrix(np.asarray(rotation_deg, float) + turn),
                        camera.width, camera.height, camera.lens_mm, camera.sensor_width_mm)


def jittered_lamps(lamps: dict[str, list[float]], rng: np.random.Generator, jitter: float
                   ) -> tuple[dict[str, list[float]], dict[str, float]]:
    """Each lamp (in ``lamps``' order) moved by up to ``jitter`` metres on each axis, and its energy factor drawn
    from [1 - jitter, 1 + jitter] (at least ``MIN_LAMP_ENERGY``): (positions, energy factors by lamp name)."""
    positions, energy = {}, {}
    for name, position in lamps.items():
        positions[name] = [float(v) for v in np.asarray(position, float) + rng.uniform(-jitter, jitter, size=3)]
        energy[name] = max(MIN_LAMP_ENERGY, float(rng.uniform(1.0 - jitter, 1.0 + jitter)))
    return positions, energy
