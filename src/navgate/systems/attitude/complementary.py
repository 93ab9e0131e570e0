"""Quaternion complementary filter (gyro integration blended with accelerometer/magnetometer
attitude), and the accelerometer/magnetometer attitude itself. NED navigation frame, FRD body.

Reference: the classic complementary filter (W. T. Higgins, "A comparison of complementary
and Kalman filtering", IEEE Trans. AES 11(3), 1975), in the quaternion form of
R. G. Valenti, I. Dryanovski, J. Xiao, "Keeping a good attitude: a quaternion-based
orientation filter for IMUs and MARGs", Sensors 15(8), 2015, section 2 (prediction by the
gyro, correction toward the accelerometer/magnetometer quaternion), with the simple
normalised-lerp blend.

Per sample k (period h = t_k - t_{k-1}):

1. prediction ``q_w = q_{k-1} (x) exp(omega_k h / 2)`` (exact rotation-vector quaternion);
2. measurement ``q_am`` (:func:`accel_mag_quat`): roll = atan2(u_y, u_z),
   pitch = asin(-u_x) with u = -f/|f| the down direction in the body (a level FRD
   accelerometer reads f = (0, 0, -g)); yaw from the tilt-compensated magnetometer,
   ``atan2(sin(roll) m_z - cos(roll) m_y, cos(pitch) m_x + sin(pitch)(sin(roll) m_y +
   cos(roll) m_z))`` (magnetic north); without a magnetometer the predicted yaw is kept;
3. blend ``q_k = normalise((1 - alpha) q_w + alpha q_am)`` with q_am's sign chosen on q_w's
   hemisphere. ``alpha`` is the correction gain per sample (time constant ~ h / alpha).

A zero specific force (free fall) skips the correction for that sample.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _euler_quat(roll, pitch, yaw):
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


@njit(cache=True)
def _yaw_of(q0, q1, q2, q3):
    return math.atan2(2.0 * (q1 * q2 + q0 * q3), 1.0 - 2.0 * (q2 * q2 + q3 * q3))


@njit(cache=True)
def accel_mag_angles(fx, fy, fz, mx, my, mz, use_mag, yaw_default):
    """(roll, pitch, yaw, ok) from specific force f (FRD) and magnetometer m (FRD)."""
    n = math.sqrt(fx * fx + fy * fy + fz * fz)
    if not n > 0.0:
        return 0.0, 0.0, yaw_default, False
    ux, uy, uz = -fx / n, -fy / n, -fz / n
    roll = math.atan2(uy, uz)
    pitch = math.asin(min(1.0, max(-1.0, -ux)))
    yaw = yaw_default
    if use_mag and (mx * mx + my * my + mz * mz) > 0.0:
        sr, cr = math.sin(roll), math.cos(roll)
        sp, cp = math.sin(pitch), math.cos(pitch)
        yaw = math.atan2(sr * mz - cr * my, cp * mx + sp * (sr * my + cr * mz))
    return roll, pitch, yaw, True


def accel_mag_quat(acc, mag=None) -> np.ndarray:
    """Quaternion (of C_b^n) from one specific-force sample and an optional magnetometer
    sample; raises ValueError for a zero specific force."""
    acc = np.asarray(acc, dtype=np.float64)
    use_mag = mag is not None
    m = np.zeros(3) if mag is None else np.asarray(mag, dtype=np.float64)
    roll, pitch, yaw, ok = accel_mag_angles(acc[0], acc[1], acc[2], m[0], m[1], m[2], use_mag,
                                            0.0)
    if not ok:
        raise ValueError("cannot level on a zero specific force")
    return np.array(_euler_quat(roll, pitch, yaw))


@njit(cache=True)
def complementary_steps(gyro, acc, mag, dt, state, alpha, use_mag, out):
    """Advance the quaternion ``state`` (4,) by every sample, in place, writing the attitude
    after sample k into ``out[k]`` (no renormalisation of the incoming state: a log in pieces
    gives the same bits as the whole log)."""
    a0, a1, a2, a3 = state[0], state[1], state[2], state[3]
    for k in range(gyro.shape[0]):
        h = dt[k]
        tx, ty, tz = gyro[k, 0] * h, gyro[k, 1] * h, gyro[k, 2] * h
        ang = math.sqrt(tx * tx + ty * ty + tz * tz)
        if ang < 1e-6:
            d0 = 1.0 - ang * ang / 8.0
            s = 0.5 - ang * ang / 48.0
        else:
            d0 = math.cos(0.5 * ang)
            s = math.sin(0.5 * ang) / ang
        d1, d2, d3 = s * tx, s * ty, s * tz
        p0 = a0 * d0 - a1 * d1 - a2 * d2 - a3 * d3
        p1 = a0 * d1 + a1 * d0 + a2 * d3 - a3 * d2
        p2 = a0 * d2 - a1 * d3 + a2 * d0 + a3 * d1
        p3 = a0 * d3 + a1 * d2 - a2 * d1 + a3 * d0
        roll, pitch, yaw, ok = accel_mag_angles(acc[k, 0], acc[k, 1], acc[k, 2], mag[k, 0],
                                                mag[k, 1], mag[k, 2], use_mag,
                                                _yaw_of(p0, p1, p2, p3))
        if ok:
            m0, m1, m2, m3 = _euler_quat(roll, pitch, yaw)
            if m0 * p0 + m1 * p1 + m2 * p2 + m3 * p3 < 0.0:
                m0, m1, m2, m3 = -m0, -m1, -m2, -m3
            p0 = (1.0 - alpha) * p0 + alpha * m0
            p1 = (1.0 - alpha) * p1 + alpha * m1
            p2 = (1.0 - alpha) * p2 + alpha * m2
            p3 = (1.0 - alpha) * p3 + alpha * m3
        nr = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
        a0, a1, a2, a3 = p0 / nr, p1 / nr, p2 / nr, p3 / nr
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = a0, a1, a2, a3
    state[0], state[1], state[2], state[3] = a0, a1, a2, a3


@njit(cache=True)
def complementary_batch(gyro, acc, mag, dt, q0, alpha, use_mag):
    """Run the filter over a log: (N, 4) quaternions; Q[0] = q0, sample k >= 1 updates."""
    n = gyro.shape[0]
    out = np.empty((n, 4))
    nq = math.sqrt(q0[0] * q0[0] + q0[1] * q0[1] + q0[2] * q0[2] + q0[3] * q0[3])
    state = np.zeros(4)
    for i in range(4):
        state[i] = q0[i] / nq
        out[0, i] = state[i]
    complementary_steps(gyro[1:], acc[1:], mag[1:], dt[1:], state, alpha, use_mag, out[1:])
    return out


def run_complementary(gyro, acc, mag=None, *, t, alpha: float = 0.02, q0=None) -> np.ndarray:
    """Convenience wrapper: ``t`` (N,) s, gyro rad/s, specific force, optional magnetometer
    (FRD). ``q0`` defaults to the accelerometer/magnetometer attitude of the first sample."""
    from navgate.nav import validate

    if not 0.0 <= alpha <= 1.0:
        raise ValueError(f"alpha: complementary gain must be in [0, 1], got {alpha}")
    gyro = np.ascontiguousarray(validate.finite_array("gyro", gyro, (-1, 3)))
    n = gyro.shape[0]
    acc = np.ascontiguousarray(validate.finite_array("acc", acc, (n, 3)))
    use_mag = mag is not None
    m = (np.ascontiguousarray(validate.finite_array("mag", mag, (n, 3))) if use_mag
         else np.zeros_like(gyro))
    t = validate.finite_array("t", t, (n,))
    dts = np.concatenate([[0.0], np.diff(t)])
    if n > 1 and not (dts[1:] > 0).all():
        raise ValueError("t: time must strictly increase")
    if q0 is None:
        q0 = accel_mag_quat(acc[0], m[0] if use_mag else None)
    else:
        q0 = validate.unit_quaternion("q0", q0)
    return complementary_batch(gyro, acc, m, dts, np.asarray(q0, dtype=np.float64), alpha,
                               use_mag)
