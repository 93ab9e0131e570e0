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


# ------------------------------------------------------------------ float32 bit-true face


@dataclass(frozen=True)
class ImuCalibrationFp32:
    """The calibration parameters as the float32 registers of seed 000 hold them (uint32 bit
    patterns, :mod:`navgate.numerics.fp32`): one LSB size, bias (3) and matrix (3x3) per sensor.
    """

    gyro_lsb: np.uint32
    accel_lsb: np.uint32
    gyro_bias: np.ndarray  #: (3,) uint32
    accel_bias: np.ndarray  #: (3,) uint32
    gyro_matrix: np.ndarray  #: (3, 3) uint32, row-major
    accel_matrix: np.ndarray  #: (3, 3) uint32


def calibration_to_fp32(cal: ImuCalibration) -> ImuCalibrationFp32:
    """Round every parameter to float32 (round to nearest even) as the PS writes the registers."""
    from navgate.numerics.fp32 import f32_to_bits, flush_subnormal

    def words(x):
        return flush_subnormal(f32_to_bits(np.asarray(x, float)))

    return ImuCalibrationFp32(words(cal.gyro_lsb), words(cal.accel_lsb), words(cal.gyro_bias),
                              words(cal.accel_bias), words(cal.gyro_matrix),
                              words(cal.accel_matrix))


def apply_calibration_fp32(cal: ImuCalibrationFp32, gyro_words, accel_words):
    """Seed 000's ``imu_calibration`` in float32, the bit-true face of the gateware block.

    For each sensor and sample (int16 words ``w``, shape (N, 3)), in exactly this order::

        x_j = fp32_sub(fp32_mul(fp32_from_int(w_j, 16), lsb), bias_j)          j = 0, 1, 2
        y_i = fp32_add(fp32_add(fp32_mul(M_i0, x_0), fp32_mul(M_i1, x_1)),
                       fp32_mul(M_i2, x_2))                                      i = 0, 1, 2

    (round to nearest even, subnormals flushed). Returns ``(gyro, accel)`` as (N, 3) uint32
    bit patterns (rad/s and m/s^2). Words outside int16 raise ``ValueError``.
    """
    from navgate.numerics.fp32 import fp32_add, fp32_from_int, fp32_mul, fp32_sub

    def one(words, lsb, bias, matrix):
        w = np.asarray(words)
        if w.ndim != 2 or w.shape[1] != 3:
            raise ValueError("words must be an (N, 3) array of int16 values")
        x = fp32_sub(fp32_mul(fp32_from_int(w.astype(np.int64), 16), lsb), bias[None, :])
        out = np.empty(w.shape, np.uint32)
        for i in range(3):
            out[:, i] = fp32_add(fp32_add(fp32_mul(matrix[i, 0], x[:, 0]),
                                          fp32_mul(matrix[i, 1], x[:, 1])),
                                 fp32_mul(matrix[i, 2], x[:, 2]))
        return out

    return (one(gyro_words, cal.gyro_lsb, cal.gyro_bias, cal.gyro_matrix),
            one(accel_words, cal.accel_lsb, cal.accel_bias, cal.accel_matrix))
