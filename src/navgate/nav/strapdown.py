"""Strapdown inertial navigation in the NED local-level frame (seed 000 "INS Mechanization").

One step, for IMU readings that are *interval averages* over [t_{k-1}, t_k] (what an
ADIS16500 delivers: its outputs are averaged and decimated, so angular rate times dt is
the angle increment over the sample period):

1. bias-compensated gyro w (rad/s) -> rotation vector w dt -> exact delta quaternion
   dq_b = [cos(|w|dt/2), w/|w| sin(|w|dt/2)] with the small-angle branch (seed 000 Step 1-2);
2. q <- q (x) dq_b (seed 000 Step 3), then the navigation-frame rotation over dt,
   q <- dq_n (x) q with dq_n the quaternion of -(w_ie + w_en) dt, so that a MEMS gyro's
   sensing of the 15 deg/h Earth rate is removed (seed 000 omits this; a navigation-grade
   mechanization needs it, Groves 2013 sec. 5.4); normalise (seed 000 Step 4);
3. C_b^n from q (seed 000 "DCM from Quaternion");
4. specific force to NED with the trapezoid over the interval, f_n = (C_{k-1} + C_k)/2 f_b.
   Seed 000 writes v[k] = v[k-1] + (a[k] + a[k-1]) dt/2 for instantaneous samples; with
   interval-average samples the same trapezoid belongs on the attitude that resolves the
   average specific force (it is the second-order rotation compensation of Savage 2000,
   ch. 7). docs/decisions.md records the departure;
5. velocity: v_k = v_{k-1} + (f_n + g - (2 w_ie + w_en) x v_{k-1}) dt with normal gravity
   (navgate.nav.earth);
6. position: trapezoidal in velocity, on geodetic latitude, longitude and height:
   lat += (vN_{k-1}+vN_k)/2 / (R_N+h) dt, lon += (vE_{k-1}+vE_k)/2 / ((R_E+h) cos lat) dt,
   h -= (vD_{k-1}+vD_k)/2 dt.

Earth- and transport-rate terms, gravity and radii are evaluated at the start of the
interval. :func:`imu_from_states` inverts exactly this step, which is how the scenario
simulator makes IMU readings consistent with a truth trajectory (see navgate.sim.trajectory).

The navigation state is a float64 array ``nav = [lat, lon, h, vN, vE, vD, q0, q1, q2, q3]``
(rad, rad, m, m/s, Hamilton quaternion C_b^n).

References: seed 000 "INS Mechanization"; Groves (2013) sec. 5.4-5.5; Savage (2000) ch. 7.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from navgate.nav.earth import E2, GAMMA_E, M_RATIO, OMEGA_IE, SOMIGLIANA_K, A, F
from navgate.nav.rotations import SMALL_ANGLE_RAD  # noqa: F401 (the series covers it)
from navgate.nav.rotations import dcm_from_quat_into as _dcm

NAV_SIZE = 10
#: rotation angle (rad) below which a sample's rotation uses the Taylor series (0.02 rad in
#: one 400 Hz sample is 460 deg/s)
SERIES_ANGLE_RAD = 0.02
LAT, LON, HGT, VN, VE, VD, Q0 = 0, 1, 2, 3, 4, 5, 6


@njit(cache=True, inline="always")
def _frame_terms(lat, h, vn, ve):
    """Radii, Earth rate, transport rate and gravity at the start of an interval."""
    s = math.sin(lat)
    c = math.cos(lat)
    d = 1.0 - E2 * s * s
    re = A / math.sqrt(d)
    rn = re * (1.0 - E2) / d
    wie_n = OMEGA_IE * c
    wie_d = -OMEGA_IE * s
    wen_n = ve / (re + h)
    wen_e = -vn / (rn + h)
    wen_d = -ve * (s / c) / (re + h)
    g0 = GAMMA_E * (1.0 + SOMIGLIANA_K * s * s) / math.sqrt(d)
    g = g0 * (1.0 - 2.0 / A * (1.0 + F + M_RATIO - 2.0 * F * s * s) * h + 3.0 * h * h / (A * A))
    return rn, re, c, wie_n, wie_d, wen_n, wen_e, wen_d, g


@njit(cache=True, inline="always")
def _rotvec_quat(x, y, z):
    """Quaternion components of the rotation vector (x, y, z), small-angle branch included.

    Below SERIES_ANGLE_RAD the half-angle cosine and sin(a/2)/a come from their Taylor
    series through a^6 (the next terms, a^8/10321920 and a^8/185794560, are under 3e-22 there:
    below float64 rounding), which saves a sqrt, a sin and a cos per sample (issue 32); below
    SMALL_ANGLE_RAD the higher terms vanish in rounding and this is the two-term branch.
    """
    a2 = x * x + y * y + z * z
    if a2 < SERIES_ANGLE_RAD * SERIES_ANGLE_RAD:
        a4 = a2 * a2
        w = 1.0 - a2 / 8.0 + a4 * (1.0 / 384.0) - a4 * a2 * (1.0 / 46080.0)
        s = 0.5 - a2 / 48.0 + a4 * (1.0 / 3840.0) - a4 * a2 * (1.0 / 645120.0)
    else:
        a = math.sqrt(a2)
        w = math.cos(0.5 * a)
        s = math.sin(0.5 * a) / a
    return w, s * x, s * y, s * z


@njit(cache=True, inline="always")
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@njit(cache=True, inline="always")
def mechanize_step(nav, gyro, accel, dt, c_old, c_new, f_n):
    """Advance ``nav`` in place by one IMU interval.

    gyro, accel: bias-compensated interval-average angular rate (rad/s) and specific force
    (m/s^2) in body axes. c_old, c_new (3x3) and f_n (3) are work arrays; on return they hold
    C_b^n at the start and end of the interval and the NED specific force used.
    """
    lat = nav[0]
    h = nav[2]
    vn = nav[3]
    ve = nav[4]
    vd = nav[5]
    rn, re, clat, wie_n, wie_d, wen_n, wen_e, wen_d, g = _frame_terms(lat, h, vn, ve)

    q0, q1, q2, q3 = nav[6], nav[7], nav[8], nav[9]
    _dcm(q0, q1, q2, q3, c_old)
    # body rotation over the interval, then the rotation of the navigation frame
    d0, d1, d2, d3 = _rotvec_quat(gyro[0] * dt, gyro[1] * dt, gyro[2] * dt)
    q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, d0, d1, d2, d3)
    n0, n1, n2, n3 = _rotvec_quat(-(wie_n + wen_n) * dt, -wen_e * dt, -(wie_d + wen_d) * dt)
    q0, q1, q2, q3 = _qmul(n0, n1, n2, n3, q0, q1, q2, q3)
    norm = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    q0 /= norm
    q1 /= norm
    q2 /= norm
    q3 /= norm
    _dcm(q0, q1, q2, q3, c_new)

    for i in range(3):
        f_n[i] = 0.5 * ((c_old[i, 0] + c_new[i, 0]) * accel[0]
                        + (c_old[i, 1] + c_new[i, 1]) * accel[1]
                        + (c_old[i, 2] + c_new[i, 2]) * accel[2])
    # Coriolis and transport: (2 w_ie + w_en) x v
    wx = 2.0 * wie_n + wen_n
    wy = wen_e
    wz = 2.0 * wie_d + wen_d
    cor_n = wy * vd - wz * ve
    cor_e = wz * vn - wx * vd
    cor_d = wx * ve - wy * vn
    vn_new = vn + (f_n[0] - cor_n) * dt
    ve_new = ve + (f_n[1] - cor_e) * dt
    vd_new = vd + (f_n[2] + g - cor_d) * dt

    nav[0] = lat + 0.5 * (vn + vn_new) / (rn + h) * dt
    nav[1] = nav[1] + 0.5 * (ve + ve_new) / ((re + h) * clat) * dt
    nav[2] = h - 0.5 * (vd + vd_new) * dt
    nav[3] = vn_new
    nav[4] = ve_new
    nav[5] = vd_new
    nav[6] = q0
    nav[7] = q1
    nav[8] = q2
    nav[9] = q3


@njit(cache=True)
def integrate(nav0, gyro, accel, dt):
    """Run the mechanization over N readings; returns the (N+1, 10) navigation states."""
    n = gyro.shape[0]
    out = np.empty((n + 1, NAV_SIZE))
    nav = nav0.copy()
    out[0] = nav
    c_old = np.empty((3, 3))
    c_new = np.empty((3, 3))
    f_n = np.empty(3)
    for k in range(n):
        mechanize_step(nav, gyro[k], accel[k], dt, c_old, c_new, f_n)
        out[k + 1] = nav
    return out


@njit(cache=True)
def integrate_final(nav0, gyro, accel, dt):
    """Run the mechanization over N readings and return only the final state (benchmarks)."""
    nav = nav0.copy()
    c_old = np.empty((3, 3))
    c_new = np.empty((3, 3))
    f_n = np.empty(3)
    for k in range(gyro.shape[0]):
        mechanize_step(nav, gyro[k], accel[k], dt, c_old, c_new, f_n)
    return nav


@njit(cache=True)
def imu_from_states(states, dt):
    """Exact inverse of :func:`mechanize_step`.

    Given navigation states at N+1 consecutive sample times (rows of ``states``, whose
    positions must already follow the step's trapezoidal position update), return the N
    interval-average gyro and accelerometer readings (body axes) that make the mechanization
    reproduce the states. Used by the scenario simulator; it shares the frame terms with the
    mechanization, so tests check its output against independent physics as well.
    """
    n = states.shape[0] - 1
    gyro = np.empty((n, 3))
    accel = np.empty((n, 3))
    c_old = np.empty((3, 3))
    c_new = np.empty((3, 3))
    m = np.empty((3, 3))
    for k in range(n):
        s0 = states[k]
        s1 = states[k + 1]
        lat, h, vn, ve, vd = s0[0], s0[2], s0[3], s0[4], s0[5]
        rn, re, clat, wie_n, wie_d, wen_n, wen_e, wen_d, g = _frame_terms(lat, h, vn, ve)
        # dq_b = q_{k-1}* (x) dq_n* (x) q_k
        n0, n1, n2, n3 = _rotvec_quat(-(wie_n + wen_n) * dt, -wen_e * dt, -(wie_d + wen_d) * dt)
        a0, a1, a2, a3 = _qmul(n0, -n1, -n2, -n3, s1[6], s1[7], s1[8], s1[9])
        b0, b1, b2, b3 = _qmul(s0[6], -s0[7], -s0[8], -s0[9], a0, a1, a2, a3)
        if b0 < 0.0:
            b0, b1, b2, b3 = -b0, -b1, -b2, -b3
        sv = math.sqrt(b1 * b1 + b2 * b2 + b3 * b3)
        if sv < 1e-15:
            scale = 2.0 / b0
        else:
            scale = 2.0 * math.atan2(sv, b0) / sv
        gyro[k, 0] = b1 * scale / dt
        gyro[k, 1] = b2 * scale / dt
        gyro[k, 2] = b3 * scale / dt
        # specific force: solve (C_{k-1} + C_k)/2 f_b = dv/dt - g + cor
        _dcm(s0[6], s0[7], s0[8], s0[9], c_old)
        _dcm(s1[6], s1[7], s1[8], s1[9], c_new)
        for i in range(3):
            for j in range(3):
                m[i, j] = 0.5 * (c_old[i, j] + c_new[i, j])
        wx = 2.0 * wie_n + wen_n
        wy = wen_e
        wz = 2.0 * wie_d + wen_d
        rhs = np.empty(3)
        rhs[0] = (s1[3] - vn) / dt + (wy * vd - wz * ve)
        rhs[1] = (s1[4] - ve) / dt + (wz * vn - wx * vd)
        rhs[2] = (s1[5] - vd) / dt - g + (wx * ve - wy * vn)
        accel[k] = np.linalg.solve(m, rhs)
    return gyro, accel


@njit(cache=True)
def integrate_position(lat0, lon0, h0, v_ned, dt):
    """Positions from velocities with exactly the mechanization's trapezoidal update.

    The scenario simulator defines truth positions this way (the truncation error against
    the continuous integral is O(dt^2) per unit time: micrometres at 400 Hz).
    """
    n = v_ned.shape[0]
    lat = np.empty(n)
    lon = np.empty(n)
    h = np.empty(n)
    lat[0], lon[0], h[0] = lat0, lon0, h0
    for k in range(1, n):
        s = math.sin(lat[k - 1])
        d = 1.0 - E2 * s * s
        re = A / math.sqrt(d)
        rn = re * (1.0 - E2) / d
        lat[k] = lat[k - 1] + 0.5 * (v_ned[k - 1, 0] + v_ned[k, 0]) / (rn + h[k - 1]) * dt
        lon[k] = lon[k - 1] + 0.5 * (v_ned[k - 1, 1] + v_ned[k, 1]) / (
            (re + h[k - 1]) * math.cos(lat[k - 1])) * dt
        h[k] = h[k - 1] - 0.5 * (v_ned[k - 1, 2] + v_ned[k, 2]) * dt
    return lat, lon, h


def make_nav_state(lat, lon, h, v_ned, q):
    """Pack a navigation state array from its parts (angles in rad)."""
    nav = np.empty(NAV_SIZE)
    nav[0], nav[1], nav[2] = lat, lon, h
    nav[3:6] = v_ned
    nav[6:10] = np.asarray(q, float) / np.linalg.norm(q)
    return nav
