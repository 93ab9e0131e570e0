"""Seed 002's geodetic INS: latitude, longitude, height, NED velocity and attitude, with Earth
rate and transport rate, integrated by fourth-order Runge-Kutta (100 Hz in the scenario).

Reference: seed 002 (Bhogadi, Gottapu, Konala, "MicroBlaze implementation of GPS/INS
integrated system on Virtex-6 FPGA", 2015), "INS module" (eqs. 4-11: Earth rate
Omega (cos lat, 0, -sin lat), transport rate omega' = (mu_dot cos lat, -lat_dot,
-mu_dot sin lat), gyro rates minus DCM (Omega + omega'), lat_dot = V_N / R,
mu_dot = V_E / (R cos lat), h_dot = -V_D, "the fourth order Runge-Kutta method is used to
carry out all the integrations") and eq. 22 (v_dot = C_b^n f^b - (2 Omega + omega') x v +
gamma^n). The paper integrates body velocities (U, V, W) of its flight-dynamics model; an
INS fed by an IMU integrates the NED velocity equation 22 directly, which is what this
module does (docs/seed002-gpsins.md).

State ``x = [lat, lon, h, vN, vE, vD, q0, q1, q2, q3]`` (rad, rad, m, m/s, Hamilton
quaternion of C_b^n), the same layout as :mod:`navgate.nav.strapdown`. Derivatives:

    lat' = vN / (R_M + h),  lon' = vE / ((R_N + h) cos lat),  h' = -vD
    v'   = C_b^n f_b - (2 w_ie + w_en) x v + (0, 0, g)
    q'   = q (x) (0, w_nb) / 2,   w_nb = w_ib - C_n^b (w_ie + w_en)

with w_ie = Omega (cos lat, 0, -sin lat), w_en = (vE/(R_N+h), -vN/(R_M+h),
-vE tan(lat)/(R_N+h)). Two Earth models: ``EARTH_WGS84`` (navgate.nav.earth: meridian and
transverse radii, Somigliana normal gravity with height correction) for the INS, and
``EARTH_SPHERE`` (the paper's "R_e considered a constant", gamma = gamma_0 (R_e/(R_e+h))^2)
against which the error model's F is checked by finite differences.

IMU readings are interval averages over [t_k, t_k+1] (navgate.sim.trajectory) and are held
constant across the RK4 step (zero-order hold).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from navgate.nav.earth import OMEGA_IE, gravity, radii
from navgate.nav.rotations import dcm_from_quat_into

EARTH_WGS84 = 0
EARTH_SPHERE = 1
#: the sphere used for the finite-difference check of F (paper: R_e constant)
SPHERE_RADIUS = 6371000.0
SPHERE_GAMMA0 = 9.80665


@njit(cache=True)
def earth_terms(lat, h, kind):
    """(R_M, R_N, g) for the chosen Earth model (radii without h)."""
    if kind == EARTH_SPHERE:
        r = SPHERE_RADIUS
        s = r / (r + h)
        return r, r, SPHERE_GAMMA0 * s * s
    rm, rn = radii(lat)
    return rm, rn, gravity(lat, h)


@njit(cache=True)
def dcm_from_quat(q0, q1, q2, q3):
    """C_b^n of (q0, q1, q2, q3): navgate.nav.rotations' kernel, returned as a new array."""
    c = np.empty((3, 3))
    dcm_from_quat_into(q0, q1, q2, q3, c)
    return c


@njit(cache=True)
def derivatives(x, f_b, w_ib, kind):
    """dx/dt of the geodetic INS (see the module docstring)."""
    lat, h = x[0], x[2]
    vn, ve, vd = x[3], x[4], x[5]
    q0, q1, q2, q3 = x[6], x[7], x[8], x[9]
    rm, rn, g = earth_terms(lat, h, kind)
    rmh = rm + h
    rnh = rn + h
    cl = math.cos(lat)
    sl = math.sin(lat)
    tl = sl / cl
    out = np.empty(10)
    out[0] = vn / rmh
    out[1] = ve / (rnh * cl)
    out[2] = -vd
    wie_n, wie_d = OMEGA_IE * cl, -OMEGA_IE * sl
    wen_n, wen_e, wen_d = ve / rnh, -vn / rmh, -ve * tl / rnh
    c = dcm_from_quat(q0, q1, q2, q3)
    fn = c[0, 0] * f_b[0] + c[0, 1] * f_b[1] + c[0, 2] * f_b[2]
    fe = c[1, 0] * f_b[0] + c[1, 1] * f_b[1] + c[1, 2] * f_b[2]
    fd = c[2, 0] * f_b[0] + c[2, 1] * f_b[1] + c[2, 2] * f_b[2]
    ax, ay, az = 2.0 * wie_n + wen_n, wen_e, 2.0 * wie_d + wen_d
    out[3] = fn - (ay * vd - az * ve)
    out[4] = fe - (az * vn - ax * vd)
    out[5] = fd - (ax * ve - ay * vn) + g
    win = (wie_n + wen_n, wen_e, wie_d + wen_d)
    wx = w_ib[0] - (c[0, 0] * win[0] + c[1, 0] * win[1] + c[2, 0] * win[2])
    wy = w_ib[1] - (c[0, 1] * win[0] + c[1, 1] * win[1] + c[2, 1] * win[2])
    wz = w_ib[2] - (c[0, 2] * win[0] + c[1, 2] * win[1] + c[2, 2] * win[2])
    out[6] = 0.5 * (-q1 * wx - q2 * wy - q3 * wz)
    out[7] = 0.5 * (q0 * wx + q2 * wz - q3 * wy)
    out[8] = 0.5 * (q0 * wy - q1 * wz + q3 * wx)
    out[9] = 0.5 * (q0 * wz + q1 * wy - q2 * wx)
    return out


@njit(cache=True)
def rk4_step(x, f_b, w_ib, dt, kind):
    """One classical RK4 step with the IMU reading held over the step; q renormalised."""
    k1 = derivatives(x, f_b, w_ib, kind)
    k2 = derivatives(x + 0.5 * dt * k1, f_b, w_ib, kind)
    k3 = derivatives(x + 0.5 * dt * k2, f_b, w_ib, kind)
    k4 = derivatives(x + dt * k3, f_b, w_ib, kind)
    y = x + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    n = math.sqrt(y[6] * y[6] + y[7] * y[7] + y[8] * y[8] + y[9] * y[9])
    y[6:10] /= n
    return y


@njit(cache=True)
def run_ins(x0, gyro, accel, dt, kind):
    """Free-running INS: (N+1, 10) states from N readings."""
    n = gyro.shape[0]
    out = np.empty((n + 1, 10))
    out[0] = x0
    x = x0.copy()
    for k in range(n):
        x = rk4_step(x, accel[k], gyro[k], dt, kind)
        out[k + 1] = x
    return out
