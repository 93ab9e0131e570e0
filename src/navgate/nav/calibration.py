"""IMU calibration as seed 000's ``imu_calibration`` block: LSB scaling, bias, scale factor
and 3x3 misalignment.

    corrected = M (raw_word * LSB - bias)

with M combining the scale-factor corrections (diagonal) and misalignment (off-diagonal),
one set for the gyro and one for the accelerometer (seed 000 "IMU Calibration Parameters":
bias (3), scale (3), misalignment (9) per sensor). The seed stores scale and misalignment
separately; ``M = diag(scale) @ (I + misalignment)`` maps one form onto the other
(:meth:`ImuCalibration.from_parts`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from navgate.devices.adis16500 import ACCEL_LSB_M_S2, GYRO_LSB_RAD_S


@dataclass
class ImuCalibration:
    gyro_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))  #: rad/s
    gyro_matrix: np.ndarray = field(default_factory=lambda: np.eye(3))
    accel_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))  #: m/s^2
    accel_matrix: np.ndarray = field(default_factory=lambda: np.eye(3))
    gyro_lsb: float = GYRO_LSB_RAD_S
    accel_lsb: float = ACCEL_LSB_M_S2

    def __post_init__(self):
        for name in ("gyro_bias", "accel_bias"):
            v = np.asarray(getattr(self, name), float)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ValueError(f"{name} must be 3 finite numbers")
            setattr(self, name, v)
        for name in ("gyro_matrix", "accel_matrix"):
            m = np.asarray(getattr(self, name), float)
            if m.shape != (3, 3) or not np.all(np.isfinite(m)):
                raise ValueError(f"{name} must be a finite 3x3 matrix")
            if abs(np.linalg.det(m)) < 1e-6:
                raise ValueError(f"{name} is singular")
            setattr(self, name, m)

    @classmethod
    def from_parts(cls, *, gyro_bias=(0, 0, 0), gyro_scale=(1, 1, 1), gyro_misalignment=None,
                   accel_bias=(0, 0, 0), accel_scale=(1, 1, 1), accel_misalignment=None, **kw):
        """Build from seed 000's separate scale (3) and misalignment (3x3, zero diagonal)."""
        def combine(scale, mis):
            mis = np.zeros((3, 3)) if mis is None else np.asarray(mis, float)
            return np.diag(np.asarray(scale, float)) @ (np.eye(3) + mis)

        return cls(np.asarray(gyro_bias, float), combine(gyro_scale, gyro_misalignment),
                   np.asarray(accel_bias, float), combine(accel_scale, accel_misalignment), **kw)

    def apply(self, gyro_words, accel_words):
        """Raw words (N, 3) -> calibrated (gyro rad/s, accel m/s^2), float64."""
        g = np.asarray(gyro_words, float) * self.gyro_lsb - self.gyro_bias
        a = np.asarray(accel_words, float) * self.accel_lsb - self.accel_bias
        return g @ self.gyro_matrix.T, a @ self.accel_matrix.T
