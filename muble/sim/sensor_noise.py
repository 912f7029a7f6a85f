"""The wrist force/torque sensor as a real one reads: a bias that drifts, and white noise on every sample.

A strain-gauge force/torque sensor reads the true wrench plus, per axis of its own frame,
- white noise: each output sample (``sample_rate_hz``, the rate the sensor reports at) carries an independent
  Gaussian error of ``force_white_n`` (N) and ``torque_white_nm`` (N·m) standard deviation; between two output
  samples the reading holds, since the physics steps faster than the sensor reports;
- a bias that drifts: a random walk that starts at zero with the episode (the sensor zeroed when the robot started)
  and wanders by ``force_drift_n_per_sqrt_s`` (N/√s) and ``torque_drift_nm_per_sqrt_s`` (N·m/√s) times the square
  root of the time elapsed, in standard deviation.

Weighing subtracts a tare taken with the empty hand seconds before the reading: the white noise averages away over
the reading's window, the bias's walk in between does not, and that is what makes one reading err. A new tare and
reading err independently. A tare averages the sensor over ``TARE_WINDOW`` as a zeroing command does; the empty
hand is still then, so its force is the instant's and only the noise is averaged.

Every draw comes from the episode's stream ``sensor.wrist_noise`` (``muble.core.streams``, keyed by the run's seed
and the episode's key), in the order the sensor is read, so an episode reads the same every time it runs. A perfect
sensor (every figure zero, the default) draws nothing: its readings are what MuJoCo computes, bit for bit.
docs/physical_properties.md ("Noisy sensing") gives the real sensor the figures of ``muble_conf/noise/wrist_ft.yaml``
come from and what one reading's error is then.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from muble.core import streams
from muble.core.ranges import bounded, configured

# s of the sensor's output a tare averages: as long as weighing's reading window (``WEIGH_WINDOW`` of the weigh
# primitive's reading, muble_plugins.primitives.measure), so that the tare's white noise is as small as the reading's.
TARE_WINDOW = 0.2
# Slack on a sample index computed from the simulated time, which accumulates physics steps in floating point: a
# time meant to fall on a sample's start lands a few ulps either side of it.
_TIME_SLACK = 1e-6


@dataclass
class WristNoise:
    """How the wrist force/torque sensor errs (per axis of its frame); all zero: a perfect sensor."""

    force_white_n: float = bounded(0.0, ge=0, hint="N per output sample")
    force_drift_n_per_sqrt_s: float = bounded(0.0, ge=0, hint="N/√s, the bias's random walk")
    torque_white_nm: float = bounded(0.0, ge=0, hint="N·m per output sample")
    torque_drift_nm_per_sqrt_s: float = bounded(0.0, ge=0, hint="N·m/√s, the bias's random walk")
    sample_rate_hz: float = bounded(100.0, gt=0, hint="the sensor's output rate")

    @property
    def perfect(self) -> bool:
        """No error at all: the sensor reads what MuJoCo computes."""
        return not (self.force_white_n or self.force_drift_n_per_sqrt_s or self.torque_white_nm
                    or self.torque_drift_nm_per_sqrt_s)

    @classmethod
    def of(cls, value: Any) -> "WristNoise":
        """A checked ``WristNoise`` from None (perfect), a mapping of its fields or an object that has them (a
        config node)."""
        if value is None:
            return cls()
        if not hasattr(value, "keys"):
            value = {f.name: getattr(value, f.name) for f in fields(cls) if hasattr(value, f.name)}
        return configured(cls, value, owner="noise")


class WristSensorNoise:
    """The error of the wrist sensor's readings over one episode: drawn as the sensor is read, in the order it is
    read, from the stream of (``seed``, ``key``)."""

    def __init__(self, spec: WristNoise, seed: int, key: int):
        self.spec = spec
        self.seed, self.key = int(seed), int(key)
        self._white = np.array([spec.force_white_n] * 3 + [spec.torque_white_nm] * 3, dtype=float)
        self._drift = np.array([spec.force_drift_n_per_sqrt_s] * 3 + [spec.torque_drift_nm_per_sqrt_s] * 3,
                               dtype=float)
        self.reset()

    def reset(self) -> None:
        """Back to the episode's start: the stream from its beginning, the bias zero."""
        self._rng = streams.stream(streams.SENSOR_WRIST_NOISE, self.seed, self.key)
        self._bias = np.zeros(6)
        self._bias_sample = 0  # the output sample the bias has walked to
        self._noise = np.zeros(6)
        self._noise_sample: int | None = None  # the output sample whose white noise ``_noise`` is

    def _sample(self, time: float) -> int:
        return int(math.floor(time * self.spec.sample_rate_hz + _TIME_SLACK))

    def _advance(self, sample: int) -> None:
        if sample > self._bias_sample:
            elapsed = (sample - self._bias_sample) / self.spec.sample_rate_hz
            self._bias = self._bias + self._drift * math.sqrt(elapsed) * self._rng.standard_normal(6)
        # A state restored to an earlier time (a primitive's failed try) leaves the bias where it is: the sensor's
        # own time went on. It walks on from the restored sample.
        self._bias_sample = sample
        if sample != self._noise_sample:
            self._noise = self._white * self._rng.standard_normal(6)
            self._noise_sample = sample

    def error(self, time: float) -> np.ndarray:
        """The error (6,: force N, torque N·m, in the sensor's frame) of the reading at simulated ``time``."""
        self._advance(self._sample(time))
        return self._bias + self._noise

    def zero_error(self, time: float, window: float = TARE_WINDOW) -> np.ndarray:
        """The error (6,) of a zeroing at ``time`` that averages the sensor's output over ``window`` seconds: the
        bias then, and the white noise of that many output samples averaged."""
        self._advance(self._sample(time))
        samples = max(1, round(window * self.spec.sample_rate_hz))
        return self._bias + self._white / math.sqrt(samples) * self._rng.standard_normal(6)


def wrist_sensor_noise(noise: Any, seed: int, key: int) -> WristSensorNoise | None:
    """The episode's sensor error for the figures ``noise`` (``WristNoise.of``), or None for a perfect sensor (no
    stream is made then)."""
    spec = WristNoise.of(noise)
    return None if spec.perfect else WristSensorNoise(spec, seed, key)
