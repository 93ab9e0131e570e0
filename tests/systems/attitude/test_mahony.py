"""Seed 003 float64 reference: behaviour (convergence, signs), and the Numba batch filter
against the per-module reference."""

import math

import numpy as np
import pytest

from navgate.nav.rotations import euler_to_dcm
from navgate.systems.attitude import mahony as ref


def sensors_for(roll, pitch, yaw, p, field=(0.48, 0.0, 0.88)):
    """Noise-free accelerometer and magnetometer readings of a static sensor, in the
    filter's own convention (accel +g along nav z for accel_sign = +1; the circuit reads
    the magnetometer through mag_sign)."""
    cnb = euler_to_dcm(roll, pitch, yaw).T
    acc = p.accel_sign * (cnb @ np.array([0.0, 0.0, 1.0])) * 9.8
    mag = np.asarray(p.mag_sign) * (cnb @ np.asarray(field))
    return acc, mag


@pytest.mark.parametrize("params", [ref.SEED003, ref.NED_SI], ids=["seed003", "ned"])
@pytest.mark.parametrize("angles", [(20.0, -10.0, 50.0), (-35.0, 25.0, 200.0)])
def test_converges_to_the_static_attitude(params, angles):
    """From the reset attitude, a static sensor: the estimate converges to the true angles.
    Linearised about the truth, the attitude error obeys d'' + Kp G d' + Ki G d = 0 with G
    the symmetric gain of the two cross products, G ~ 2I - a a' - m m' (unit a, m), whose
    eigenvalues lie in [g_min, 2] with g_min = 1 - |a.m|. Along an eigenvector with gain g
    the decay rate is Kp g / 2 (complex roots) or the slow root, which exceeds
    Ki g / (Kp g) = Ki / Kp (product of roots over their sum). So every mode decays at
    least as fast as lambda = min(Ki / Kp, Kp g_min / 2). Run ln(1e8) / lambda seconds: the
    initial error (< 200 deg) shrinks below 1e-5 deg even with a transient gain of 5."""
    roll, pitch, yaw = (math.radians(a) for a in angles)
    acc, mag = sensors_for(roll, pitch, yaw, params)
    g_min = 1 - abs(np.dot(acc, mag)) / np.linalg.norm(acc) / np.linalg.norm(mag)
    lam = min(params.ki / params.kp, params.kp * g_min / 2)
    n = int(math.log(1e8) / lam / params.dt) + 1
    q = ref.run_mahony(np.zeros((n, 3)), np.tile(acc, (n, 1)), np.tile(mag, (n, 1)),
                       params=params)
    pitch_, roll_, yaw_ = ref.euler_from_dcm(ref.dcm_from_quat(q[-1]))
    assert roll_ == pytest.approx(angles[0], abs=1e-5)
    assert pitch_ == pytest.approx(angles[1], abs=1e-5)
    assert yaw_ == pytest.approx(angles[2] % 360, abs=1e-5)
    # and the per-module reference agrees with the batch run after 300 solves
    circuit = ref.MahonyCircuitReference(params)
    for _ in range(300):
        r = circuit.solve(acc, mag, np.zeros(3))
    np.testing.assert_allclose(r.q, q[300], atol=1e-12)


def test_integral_term_cancels_a_gyro_bias():
    """A constant gyro bias is absorbed by the integral state: at steady state the corrected
    rate is zero, so the integral equals minus the bias and the attitude error vanishes.
    Decay rate as in the convergence test: lambda = min(Ki/Kp, Kp g_min/2) = 0.5/s here
    (field dip chosen so g_min = 1 - |a.m| = 0.68); ln(1e8)/lambda = 37 s, the bias
    (<= 0.03) is then matched to 1e-9."""
    p = ref.MahonyParams(kp=2.0, ki=1.0, dt=0.01, gyro_scale=1.0, mag_sign=(1, 1, 1))
    field = (0.9, 0.0, 0.3)
    acc, mag = sensors_for(0.1, -0.2, 0.3, p, field=field)
    bias = np.array([0.02, -0.01, 0.03])
    circuit = ref.MahonyCircuitReference(p)
    for _ in range(int(math.log(1e8) / 0.5 / p.dt) + 1):
        r = circuit.solve(acc, mag, bias)
    np.testing.assert_allclose(r.integral, -bias, atol=1e-9)
    np.testing.assert_allclose(r.omega, 0.0, atol=1e-9)
    assert r.roll == pytest.approx(math.degrees(0.1), abs=1e-6)


def test_batch_filter_equals_per_module_reference():
    """mahony_batch (Numba, whole log) and MahonyCircuitReference run the same equations in
    the same order: over 500 random samples they agree to a few float64 ulps (1e-12)."""
    rng = np.random.default_rng(7)
    n = 500
    gyro = rng.normal(0, 30, (n, 3))
    acc = rng.normal(0, 1, (n, 3)) + [0, 0, 9.8]
    mag = rng.normal(0, 0.2, (n, 3)) + [0.4, 0.1, 0.9]
    p = ref.SEED003
    q = ref.run_mahony(gyro, acc, mag, params=p)
    circuit = ref.MahonyCircuitReference(p)
    for k in range(1, n):
        r = circuit.solve(acc[k], mag[k], gyro[k])
        np.testing.assert_allclose(q[k], r.q, atol=1e-12)


def test_batch_uses_time_column_and_skips_zero_vectors():
    t = np.array([0.0, 0.01, 0.03, 0.04])
    gyro = np.tile([0.0, 0.0, 1.0], (4, 1))
    acc = np.zeros((4, 3))  # no accelerometer correction at all
    p = ref.MahonyParams(kp=1.0, ki=0.0, gyro_scale=1.0, mag_sign=(1, 1, 1))
    q = ref.run_mahony(gyro, acc, None, t=t, params=p)
    # pure yaw integration by first-order steps: each step rotates by atan(dt/2 * w)*2
    yaw = [2 * math.atan2(q[k, 3], q[k, 0]) for k in range(4)]
    want = np.cumsum([0.0] + [2 * math.atan(0.5 * h) for h in np.diff(t)])
    np.testing.assert_allclose(yaw, want, atol=1e-12)


def test_params_validation():
    with pytest.raises(ValueError):
        ref.MahonyParams(dt=0.0)
    with pytest.raises(ValueError):
        ref.MahonyParams(kp=-1.0)
    with pytest.raises(ValueError):
        ref.MahonyParams(mag_sign=(1, 2, 1))
    with pytest.raises(ValueError):
        ref.acc_error([0, 0, 0], 0, 0, 1)
