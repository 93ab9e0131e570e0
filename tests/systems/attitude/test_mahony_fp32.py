"""Seed 003 bit-true float32 model: operation order, flush-to-zero, error bounds, atan core."""

import math

import numpy as np
import pytest

from navgate.numerics.cordic import cordic_error_bound
from navgate.numerics.fp32 import bits_to_f32, f32_to_bits
from navgate.systems.attitude import atan16
from navgate.systems.attitude import mahony as ref
from navgate.systems.attitude import mahony_fp32 as bt

U = 2.0**-24  # unit roundoff of binary32 (round to nearest)
N = 20000


def gamma(k):
    """Higham's gamma_k = k u / (1 - k u): bound on k compounded relative roundings."""
    return k * U / (1 - k * U)


def bits(x):
    return f32_to_bits(np.asarray(x, dtype=np.float32))


def f32(b_):
    return bits_to_f32(np.asarray(b_, dtype=np.uint32))


@pytest.fixture(scope="module")
def rng():
    return np.random.default_rng(20260131)


def np32_solve(state, acc, mag, gyro, p):
    """Independent transcription of the documented operation order in NumPy float32 (IEEE
    binary32, round to nearest even; identical to the model for normal-range values)."""
    f = np.float32
    q, c, integ = state
    (c11, c12, c13, c21, c22, c23, c31, c32, c33) = c
    ax, ay, az = (f(p.accel_sign) * v for v in acc)
    n = np.sqrt((ax * ax + ay * ay) + az * az)
    ax, ay, az = ax / n, ay / n, az / n
    ea = (ay * c33 - az * c23, az * c13 - ax * c33, ax * c23 - ay * c13)
    mx, my, mz = (f(s) * v for s, v in zip(p.mag_sign, mag, strict=True))
    n = np.sqrt((mx * mx + my * my) + mz * mz)
    mx, my, mz = mx / n, my / n, mz / n
    hx = (c11 * mx + c21 * my) + c31 * mz
    hy = (c12 * mx + c22 * my) + c32 * mz
    hz = (c13 * mx + c23 * my) + c33 * mz
    bx = np.sqrt(hx * hx + hy * hy)
    bz = hz
    wx, wy, wz = c11 * bx + c13 * bz, c21 * bx + c23 * bz, c31 * bx + c33 * bz
    em = (my * wz - mz * wy, mz * wx - mx * wz, mx * wy - my * wx)
    kp, ki, dt = f(p.kp), f(p.ki), f(p.dt)
    new_i, w = [], []
    for g, a, m, i in zip(gyro, ea, em, integ, strict=True):
        e = a + m
        i = i + (e * ki) * dt
        new_i.append(i)
        w.append((g * f(math.pi / 180) + kp * e) + i)
    wx, wy, wz = w
    q0, q1, q2, q3 = q
    ht = dt * f(0.5)
    d = (-((q1 * wx + q2 * wy) + q3 * wz), (q0 * wx + q2 * wz) - q3 * wy,
         (q0 * wy - q1 * wz) + q3 * wx, (q0 * wz + q1 * wy) - q2 * wx)
    r = [qi + di * ht for qi, di in zip(q, d, strict=True)]
    n = np.sqrt(((r[0] * r[0] + r[1] * r[1]) + r[2] * r[2]) + r[3] * r[3])
    q0, q1, q2, q3 = (ri / n for ri in r)
    one = f(1)
    c = (one - 2 * (q2 * q2 + q3 * q3), 2 * (q1 * q2 + q0 * q3), 2 * (q1 * q3 - q0 * q2),
         2 * (q1 * q2 - q0 * q3), one - 2 * (q1 * q1 + q3 * q3), 2 * (q2 * q3 + q0 * q1),
         2 * (q1 * q3 + q0 * q2), 2 * (q2 * q3 - q0 * q1), one - 2 * (q1 * q1 + q2 * q2))
    return (q0, q1, q2, q3), c, tuple(new_i), ea, em, tuple(w)


def test_solve_loop_bit_exact_against_numpy_float32(rng):
    """N random circuits, 20 solves each with fresh random sensor data: every intermediate
    and every state word equals the NumPy float32 transcription bit for bit."""
    p = ref.SEED003
    n = 4000
    circuit = bt.MahonyCircuitFP32(p, batch=n)
    f = np.float32
    state = ((np.ones(n, f), np.zeros(n, f), np.zeros(n, f), np.zeros(n, f)),
             tuple(np.full(n, 1.0 if i in (0, 4, 8) else 0.0, f) for i in range(9)),
             (np.zeros(n, f),) * 3)
    for _ in range(20):
        acc = tuple(rng.normal(0, 1, n).astype(f) for _ in range(3))
        mag = tuple(rng.normal(0, 1, n).astype(f) for _ in range(3))
        gyro = tuple(rng.normal(0, 50, n).astype(f) for _ in range(3))
        r = circuit.solve([bits(v) for v in acc], [bits(v) for v in mag],
                          [bits(v) for v in gyro])
        q, c, integ, ea, em, w = np32_solve(state, acc, mag, gyro, p)
        state = (q, c, integ)
        for ours, theirs in [(r.e_acc, ea), (r.e_mag, em), (r.omega, w), (r.integral, integ),
                             (r.q, q), (r.c, c)]:
            for o, t in zip(ours, theirs, strict=True):
                np.testing.assert_array_equal(o, bits(t))
        assert not r.invalid.any()


def test_acc_error_within_rounding_bound_of_float64(rng):
    """Each e_a component is fl(P1 - P2) with P = a_i c_j and a_i = x_i / sqrt(s).
    Rounding count along each product: s (3 products + 2 sums -> gamma_3 relative), sqrt
    halves that and adds u, the divide adds u, the product with c adds u: a_i c_j carries at
    most gamma_5; the final difference adds u of the result. So
    |e_fp32 - e_exact| <= gamma_6 (|P1| + |P2|), with e_exact evaluated in float64 from the
    same float32 inputs (float64's own error, ~1e-16, is far inside the margin)."""
    v = rng.normal(0, 3, (6, N)).astype(np.float32)
    e = bt.acc_error(*(bits(x) for x in v))
    a = v[:3].astype(np.float64)
    a = a / np.sqrt(np.sum(a * a, axis=0))
    c13, c23, c33 = v[3:].astype(np.float64)
    exact = [(a[1] * c33, a[2] * c23), (a[2] * c13, a[0] * c33), (a[0] * c23, a[1] * c13)]
    for ours, (p1, p2) in zip(e, exact, strict=True):
        err = np.abs(f32(ours).astype(np.float64) - (p1 - p2))
        assert np.all(err <= gamma(6) * (np.abs(p1) + np.abs(p2)))


def test_matx_within_rounding_bound(rng):
    """c12 = 2(q1 q2 + q0 q3): two products and one sum (gamma_2 on |q1 q2| + |q0 q3|), the
    doubling is exact. c11 = 1 - 2(q2^2 + q3^2): gamma_2 on 2(q2^2 + q3^2), then the
    subtraction rounds once more (u of |c11|)."""
    q = rng.normal(0, 1, (4, N)).astype(np.float32)
    c = bt.dcm_from_quat([bits(x) for x in q])
    q0, q1, q2, q3 = q.astype(np.float64)
    c12 = 2 * (q1 * q2 + q0 * q3)
    assert np.all(np.abs(f32(c[1]) - c12) <= gamma(2) * 2 * (np.abs(q1 * q2) + np.abs(q0 * q3)))
    t = 2 * (q2 * q2 + q3 * q3)
    c11 = 1 - t
    assert np.all(np.abs(f32(c[0]) - c11) <= gamma(2) * t * (1 + U) + U * np.abs(c11))


def test_flush_to_zero_inputs():
    """A subnormal accelerometer component behaves exactly as a zero (seed 003's float
    cores flush denormals; navgate.numerics.fp32 semantics)."""
    sub = np.full(1, 0x00000123, dtype=np.uint32)  # a positive subnormal
    zero = np.zeros(1, dtype=np.uint32)
    one, two = bits(np.ones(1)), bits(np.full(1, 2.0))
    c = [bits(np.full(1, v)) for v in (0.3, -0.4, 0.8)]
    e_sub = bt.acc_error(sub, one, two, *c)
    e_zero = bt.acc_error(zero, one, two, *c)
    for a_, b_ in zip(e_sub, e_zero, strict=True):
        np.testing.assert_array_equal(a_, b_)


def test_zero_accelerometer_is_flagged():
    circuit = bt.MahonyCircuitFP32(batch=2)
    acc = [bits(np.array([0.0, 0.0])), bits(np.array([0.0, 0.0])), bits(np.array([0.0, 1.0]))]
    one = bits(np.ones(2))
    r = circuit.solve(acc, [one, one, one], [one, one, one])
    assert r.invalid.tolist() == [True, False]


# ------------------------------------------------------------------------------ atan core


def atan16_bound(r):
    """Worst-case |atan_fp32(x, y) - atan2(y, x)| (rad) for inputs of magnitude >= r (real
    units, inside the Q2.13 range). Terms:
    1. input rounding to Q2.13: each coordinate moves <= 2^-14, the vector by <= sqrt(2)
       2^-14, its angle by <= asin(sqrt(2) 2^-14 / r') with r' = r - sqrt(2) 2^-14;
    2. the CORDIC on integers: residual atan(2^-(n-1)) + truncation of the shifted terms
       (navgate.numerics.cordic.cordic_error_bound's derivation, evaluated with a 48-bit
       table so its table term vanishes) + this core's radian table error
       (sum |round(atan(2^-i) 2^14) - atan(2^-i) 2^14| 2^-14);
    3. truncation of the Q2.14 accumulator to Q2.13: < 2^-13."""
    n, zf = atan16.ITERATIONS, atan16.Z_FRAC
    r_in = r - math.sqrt(2) * 2**-14
    e_in = math.asin(math.sqrt(2) * 2**-14 / r_in)
    mag_int = r_in * 2**atan16.IN_FRAC  # integer units before the guard shift
    e_cordic = cordic_error_bound(16, n, angle_bits=48, guard_bits=atan16.GUARD,
                                  min_magnitude=mag_int)
    e_table = sum(abs(round(math.atan(2.0**-i) * 2**zf) - math.atan(2.0**-i) * 2**zf)
                  for i in range(n)) * 2.0**-zf
    return e_in + e_cordic + e_table + 2.0**-13


@pytest.mark.parametrize("r_min, r_max", [(0.25, 0.5), (0.5, 1.0), (1.0, 2.0), (2.0, 2.8)])
def test_atan16_error_bound_all_quadrants(rng, r_min, r_max):
    """Random angles in all four quadrants, magnitudes in [r_min, r_max] (2.8 keeps both
    coordinates inside Q2.13's [-4, 4))."""
    r = rng.uniform(r_min, r_max, N)
    th = rng.uniform(-math.pi, math.pi, N)
    x, y = (r * np.cos(th)).astype(np.float32), (r * np.sin(th)).astype(np.float32)
    rad, fix, sat = atan16.atan_fp32(bits(x), bits(y))
    assert not sat.any()
    err = np.angle(np.exp(1j * (f32(rad).astype(np.float64)
                                - np.arctan2(y.astype(np.float64), x.astype(np.float64)))))
    assert np.max(np.abs(err)) <= atan16_bound(r_min)
    np.testing.assert_array_equal(f32(rad), fix.astype(np.float32) / np.float32(8192))


def test_atan16_bound_is_tight_enough_to_matter():
    """For unit-magnitude inputs (the Euler angles of an orthonormal C) the bound is under
    8 output LSBs (0.056 deg), and at 0.25 it is still under 0.15 deg."""
    assert atan16_bound(1.0) < 8 * 2**-13
    assert atan16_bound(0.25) < math.radians(0.15)


def test_atan16_axes_and_saturation():
    x = np.array([1.0, 0.0, -1.0, 0.0, 5.0], dtype=np.float32)
    y = np.array([0.0, 1.0, 0.0, -1.0, 0.0], dtype=np.float32)
    rad, fix, sat = atan16.atan_fp32(bits(x), bits(y))
    want = np.array([0.0, math.pi / 2, math.pi, -math.pi / 2, 0.0])
    got = f32(rad).astype(np.float64)
    # +-pi may come out as either sign; compare on the circle
    assert np.all(np.abs(np.angle(np.exp(1j * (got - want)))) <= atan16_bound(1.0))
    assert sat.tolist() == [False, False, False, False, True]


def test_bit_true_tracks_reference_over_a_long_run():
    """16 circuits, 400 solves each (0.8 s at T = 2 ms) of sensors rotating at up to
    0.6 rad/s, read without gyro so the filter follows through its corrections only: after
    the 50-solve settling (1/Kp = 0.1 s) the float32 Euler angles stay within the atan
    core's bound plus the float32 state error of the float64 reference. Float32 state error:
    the filter is contractive (gain Kp T = 0.02 per solve), so the attitude error stays at
    about one solve's rounding (~1e-7) divided by 0.02, i.e. 5e-6 rad; bound used:
    atan bound (magnitude >= 0.5) + 1e-5 rad."""
    from navgate.nav.rotations import euler_to_dcm_array

    p = ref.SEED003
    batch, steps = 16, 400
    t = np.arange(steps) * p.dt
    phase = np.linspace(0, 2 * math.pi, batch, endpoint=False)[:, None]
    roll = 0.3 * np.sin(3 * t + phase)
    pitch = 0.2 * np.sin(2 * t + 2 * phase)
    yaw = phase + 0.6 * t
    cnb = np.swapaxes(euler_to_dcm_array(roll, pitch, yaw), -1, -2)  # (batch, steps, 3, 3)
    acc = (cnb @ np.array([0.0, 0.0, 1.0])).astype(np.float32)
    mag = (np.diag(p.mag_sign) @ (cnb @ np.array([0.5, 0.0, 0.8]))[..., None])[..., 0]
    mag = mag.astype(np.float32)
    zero = bits(np.zeros(batch))
    circuit = bt.MahonyCircuitFP32(p, batch=batch)
    out32 = np.empty((steps, batch, 3))
    for k in range(steps):
        r = circuit.solve([bits(acc[:, k, i]) for i in range(3)],
                          [bits(mag[:, k, i]) for i in range(3)], [zero, zero, zero])
        out32[k] = np.column_stack([f32(r.euler.pitch), f32(r.euler.roll), f32(r.euler.yaw)])
    worst = 0.0
    for j in range(batch):
        # mahony_batch: Q[0] is the initial attitude, sample k >= 1 is one solve
        pad = np.vstack([np.zeros((1, 3)), acc[j].astype(np.float64)])
        padm = np.vstack([np.zeros((1, 3)), mag[j].astype(np.float64)])
        q = ref.run_mahony(np.zeros((steps + 1, 3)), pad, padm, params=p)[1:]
        for k in range(50, steps):
            e64 = ref.euler_from_dcm(ref.dcm_from_quat(q[k]))
            d = out32[k, j] - np.array(e64)
            d[2] = (d[2] + 180) % 360 - 180
            worst = max(worst, float(np.max(np.abs(d))))
    assert worst <= math.degrees(atan16_bound(0.5) + 1e-5)
