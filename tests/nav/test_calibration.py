"""IMU calibration (navgate.nav.calibration): the float32 bit-true face against NumPy float32 in
the same operation order, and against the float64 calibration within the rounding bound."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.nav.calibration import (
    ImuCalibration,
    apply_calibration_fp32,
    calibration_to_fp32,
)
from navgate.numerics.fp32 import bits_to_f32

U = 2.0 ** -24  # unit roundoff of binary32


def _random_calibration(rng):
    def matrix():
        return np.eye(3) + rng.normal(0, 2e-3, (3, 3))

    return ImuCalibration(rng.normal(0, 3e-3, 3), matrix(), rng.normal(0, 0.1, 3), matrix())


def test_fp32_calibration_equals_numpy_float32_in_the_documented_order():
    rng = np.random.default_rng(1)
    cal = _random_calibration(rng)
    c32 = calibration_to_fp32(cal)
    words = rng.integers(-32768, 32768, (5000, 3))
    words[:4] = [[-32768, 32767, 0], [0, 0, 0], [1, -1, 2], [32767, -32768, 32767]]
    gyro, accel = apply_calibration_fp32(c32, words, words[::-1])
    for out, w, lsb, bias, m in ((gyro, words, c32.gyro_lsb, c32.gyro_bias, c32.gyro_matrix),
                                 (accel, words[::-1], c32.accel_lsb, c32.accel_bias,
                                  c32.accel_matrix)):
        f = np.float32
        x = w.astype(f) * bits_to_f32(lsb) - bits_to_f32(bias)
        mm = bits_to_f32(m)
        y = np.stack([(mm[i, 0] * x[:, 0] + mm[i, 1] * x[:, 1]) + mm[i, 2] * x[:, 2]
                      for i in range(3)], axis=1).astype(f)
        assert np.array_equal(out, y.view(np.uint32))


def test_fp32_calibration_within_rounding_bound_of_float64():
    rng = np.random.default_rng(2)
    cal = _random_calibration(rng)
    words = rng.integers(-32768, 32768, (20000, 3))
    g64, a64 = cal.apply(words, words)
    g32, a32 = apply_calibration_fp32(calibration_to_fp32(cal), words, words)
    for y64, y32, lsb, bias, m in ((g64, g32, cal.gyro_lsb, cal.gyro_bias, cal.gyro_matrix),
                                   (a64, a32, cal.accel_lsb, cal.accel_bias,
                                    cal.accel_matrix)):
        # eight roundings on the way (lsb, bias and M to float32; mul, sub; mul; two adds),
        # each at most U relative on a term bounded by |M_ij| (|w_j lsb| + |b_j|)
        scale = (np.abs(words) * lsb + np.abs(bias)) @ np.abs(m).T
        err = np.abs(bits_to_f32(y32).astype(float) - y64)
        assert np.all(err <= 8 * U * scale * (1 + 16 * U) + 1e-45)
        assert err.max() > 0  # float32 really is in use


def test_fp32_calibration_rejects_words_outside_int16():
    cal = calibration_to_fp32(ImuCalibration())
    with pytest.raises(ValueError):
        apply_calibration_fp32(cal, np.array([[40000, 0, 0]]), np.zeros((1, 3), int))
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        apply_calibration_fp32(cal, np.zeros(3, int), np.zeros((1, 3), int))
