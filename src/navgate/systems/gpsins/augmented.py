"""Seed 002's GPS/INS with the sensors' own error states: the seed's 9 navigation error states
plus, per sensor block the IMU model really has, 3 accelerometer biases, 3 gyro biases,
3 accelerometer scale factors and 3 gyro scale factors (up to 21 states), closed loop.

Reference: the seed's 9-state filter (:mod:`navgate.systems.gpsins.filter`, seed 002 "Kalman
filter module") for the navigation block; sensor error states as in Farrell, *Aided
Navigation* (2008), ch. 11, and Groves, *Principles of GNSS, Inertial, and Multisensor
Integrated Navigation Systems* (2nd ed.), sec. 14.2 (error states for the IMU biases and
scale factors, closed-loop correction of the IMU outputs).

Sensor error model (that of :mod:`navgate.systems.gpsins.scenario`, first order): the
compensated readings the INS integrates carry the residual errors

    df = b_a + s_a (.) (f + g e_z) + n_a,      dw = b_g + s_g (.) w_ib + n_g

(``(.)`` the element-wise product; the accelerometer scale error acts on the departure from
the level-calibration point (0, 0, -g), the gyro scale error on the whole rate). The sensor
error states are these *residuals*: after an update with estimate (b_a^, s_a^, ...) the
compensation absorbs them (``f_c = f_m - B_a - S_a (.) (f_m + g e_z)`` with B_a += b_a^,
S_a += s_a^, likewise for the gyro) and the estimate is reset to 0, as the navigation
states are. With the seed's G = [[0, 0], [C_b^n, 0], [0, -C_b^n]]:

    d(dv)/dt  = F_9 ... + C_b^n (b_a + diag(f + g e_z) s_a) + C_b^n n_a
    d(eps)/dt = F_9 ... - C_b^n (b_g + diag(w_ib) s_g) - C_b^n n_g
    d(b)/dt = d(s)/dt = 0   (random constants: Table 1's offsets, drifts and scale residuals)

Process noise is the sensor model's white noise, ``Q = diag(n_a^2, n_g^2)`` per body axis;
a block the filter does not carry (``carry`` flags) is covered by noise instead, as the
seed's 9-state filter does: a bias b as density b^2 tau, a scale factor s as
(s x excitation)^2 tau on 1 s running means of the readings.

Discretisation as the seed's filter: Phi = I + F dt per IMU step, P <- Phi (P + G Q G' dt)
Phi', here evaluated with F's non-zeros only (P + dt (F P + P F') + dt^2 F P F'); F is taken
at the state at the start of the step. GPS update: the seed's scaled position rows, Joseph
form written with the rank-3 structure of H.

The forward loop stores what :mod:`navgate.systems.gpsins.smoother` needs (the posterior and
prior covariance at every GPS epoch, the corrections, the readings and process noise of
every step) so that the smoother can recompute the covariances between epochs instead of
keeping one per IMU sample.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from navgate.systems.gpsins import filter as kf
from navgate.systems.gpsins.ins import EARTH_WGS84, dcm_from_quat, rk4_step

G0 = 9.80665
NAV = 9
#: order of the optional sensor blocks in the state vector
BLOCKS = ("accel_bias", "gyro_bias", "accel_scale", "gyro_scale")


def layout(carry: tuple[bool, bool, bool, bool]) -> tuple[np.ndarray, int]:
    """Offsets of the four sensor blocks (-1 when not carried) and the state count."""
    off = np.full(4, -1, dtype=np.int64)
    n = NAV
    for i, c in enumerate(carry):
        if c:
            off[i] = n
            n += 3
    return off, n


@njit(cache=True)
def error_dynamics(x, f_c, w_c, off, n, kind):
    """F (n x n) of the augmented error state at nav state ``x`` with compensated readings."""
    F = np.zeros((n, n))
    F[:NAV, :NAV] = kf.error_dynamics(x, f_c, kind)
    C = dcm_from_quat(x[6], x[7], x[8], x[9])
    for i in range(3):
        for j in range(3):
            c = C[i, j]
            if off[0] >= 0:
                F[3 + i, off[0] + j] = c
            if off[1] >= 0:
                F[6 + i, off[1] + j] = -c
            if off[2] >= 0:
                F[3 + i, off[2] + j] = c * (f_c[j] + (G0 if j == 2 else 0.0))
            if off[3] >= 0:
                F[6 + i, off[3] + j] = -c * w_c[j]
    return F


@njit(cache=True)
def add_noise(P, x, qa, qg, dt):
    """P += G Q G' dt: blockdiag(0, C Qa C', C Qg C') dt (in place)."""
    C = dcm_from_quat(x[6], x[7], x[8], x[9])
    for i in range(3):
        for j in range(3):
            a = 0.0
            w = 0.0
            for m in range(3):
                a += C[i, m] * qa[m] * C[j, m]
                w += C[i, m] * qg[m] * C[j, m]
            P[3 + i, 3 + j] += a * dt
            P[6 + i, 6 + j] += w * dt


@njit(cache=True)
def phi_sandwich(P, F, dt, rows):
    """P <- (I + F dt) P (I + F dt)' using F's non-zeros (in place), for an F whose rows from
    ``rows`` on are zero (the sensor states are random constants: rows >= 9): T = P + dt F P
    row by row, then the upper triangle of T + dt T F', mirrored."""
    n = P.shape[0]
    ptr = np.zeros(n + 1, dtype=np.int64)
    cols = np.empty(n * n, dtype=np.int64)
    vals = np.empty(n * n)
    m = 0
    for i in range(n):
        if i >= rows:
            ptr[i + 1] = m
            continue
        for k in range(n):
            a = F[i, k]
            if a != 0.0:
                cols[m] = k
                vals[m] = a * dt
                m += 1
        ptr[i + 1] = m
    T = P.copy()
    for i in range(n):
        for q in range(ptr[i], ptr[i + 1]):
            a = vals[q]
            k = cols[q]
            for j in range(n):
                T[i, j] += a * P[k, j]
    for j in range(n):
        p0, p1 = ptr[j], ptr[j + 1]
        for i in range(j + 1):
            acc = T[i, j]
            for q in range(p0, p1):
                acc += T[i, cols[q]] * vals[q]
            P[i, j] = acc
    for j in range(n):
        for i in range(j + 1, n):
            P[i, j] = P[j, i]


@njit(cache=True)
def propagate(P, x, f_c, w_c, dt, qa, qg, off, kind):
    """One covariance step; returns F (for the smoother's recomputation)."""
    n = P.shape[0]
    F = error_dynamics(x, f_c, w_c, off, n, kind)
    add_noise(P, x, qa, qg, dt)
    phi_sandwich(P, F, dt, NAV)
    return F


@njit(cache=True)
def apply_correction(x, comp, dx, off):
    """Closed loop: the navigation block corrects the INS (the seed filter's correction), the
    sensor blocks move into the compensation ``comp`` = (B_a, B_g, S_a, S_g) (12,)."""
    kf.apply_correction(x, dx[:NAV])
    for b in range(4):
        if off[b] >= 0:
            for i in range(3):
                comp[3 * b + i] += dx[off[b] + i]


@njit(cache=True)
def compensate(f_m, w_m, comp, f_c, w_c):
    """Compensated readings (in place): f_c = f_m - B_a - S_a (.) (f_m + g e_z),
    w_c = w_m - B_g - S_g (.) w_m."""
    for i in range(3):
        dep = f_m[i] + (G0 if i == 2 else 0.0)
        f_c[i] = f_m[i] - comp[i] - comp[6 + i] * dep
        w_c[i] = w_m[i] - comp[3 + i] - comp[9 + i] * w_m[i]


@njit(cache=True)
def step_noise(f_avg, w_avg, qa0, qg0, sf_acc, sf_gyro, tau, qa, qg):
    """Per-axis densities of one step: the white floor plus the scale-factor errors of blocks
    not carried, seen as noise while the axis is excited ((sf x excitation)^2 tau)."""
    for i in range(3):
        dep = f_avg[i] + (G0 if i == 2 else 0.0)
        qa[i] = qa0[i] + (sf_acc * dep) ** 2 * tau
        qg[i] = qg0[i] + (sf_gyro * w_avg[i]) ** 2 * tau


@njit(cache=True)
def run(x0, P0, gyro, accel, dt, ep_idx, gps_lla, gps_valid, sigma, qa0, qg0, sf_acc,
        sf_gyro, tau, off):
    """The closed-loop filter over a flight.

    ``ep_idx`` (M+1,): sample index of each GPS epoch, ep_idx[0] = 0 (the start, no fix);
    ``gps_lla``/``gps_valid`` (M, .) the fixes of epochs 1..M. Returns states (N+1, 10)
    (after any correction), compensated readings f_c, w_c (N, 3), per-step densities qa, qg
    (N, 3), position covariance in metres (N+1, 3, 3), P_post, P_prior (M+1, n, n),
    corrections dx (M+1, n), compensation per epoch (M+1, 12), innovations and their
    variances (M, 3), and the valid fixes rejected for a non-finite coordinate (M,)."""
    n = P0.shape[0]
    N = gyro.shape[0]
    M = ep_idx.shape[0] - 1
    states = np.empty((N + 1, 10))
    fcs = np.empty((N, 3))
    wcs = np.empty((N, 3))
    qas = np.empty((N, 3))
    qgs = np.empty((N, 3))
    ppos = np.empty((N + 1, 3, 3))
    p_post = np.empty((M + 1, n, n))
    p_prior = np.empty((M + 1, n, n))
    dxs = np.zeros((M + 1, n))
    comps = np.zeros((M + 1, 12))
    innov = np.full((M, 3), np.nan)
    s_diag = np.full((M, 3), np.nan)
    rejected = np.zeros(M, dtype=np.bool_)
    x = x0.copy()
    P = P0.copy()
    comp = np.zeros(12)
    p_post[0] = P
    p_prior[0] = P
    states[0] = x
    qa = np.empty(3)
    qg = np.empty(3)
    f_c = np.empty(3)
    w_c = np.empty(3)
    lp = min(1.0, dt / 1.0)
    f_avg = accel[0].copy()
    w_avg = gyro[0].copy()
    e = 1
    for k in range(N):
        compensate(accel[k], gyro[k], comp, f_c, w_c)
        f_avg += lp * (f_c - f_avg)
        w_avg += lp * (w_c - w_avg)
        step_noise(f_avg, w_avg, qa0, qg0, sf_acc, sf_gyro, tau, qa, qg)
        propagate(P, x, f_c, w_c, dt, qa, qg, off, EARTH_WGS84)
        x = rk4_step(x, f_c, w_c, dt, EARTH_WGS84)
        for i in range(3):
            fcs[k, i] = f_c[i]
            wcs[k, i] = w_c[i]
            qas[k, i] = qa[i]
            qgs[k, i] = qg[i]
        if e <= M and ep_idx[e] == k + 1:
            p_prior[e] = P
            fix = gps_lla[e - 1]
            usable = gps_valid[e - 1]
            if usable and not (math.isfinite(fix[0]) and math.isfinite(fix[1])
                               and math.isfinite(fix[2])):
                rejected[e - 1] = True  # a fix with a NaN/inf coordinate: flagged, not used
                usable = False
            if usable:
                dx, z, S = kf.gps_update(P, x, fix, sigma)
                apply_correction(x, comp, dx, off)
                dxs[e] = dx
                for m in range(3):
                    innov[e - 1, m] = z[m]
                    s_diag[e - 1, m] = S[m, m]
            p_post[e] = P
            comps[e] = comp
            e += 1
        states[k + 1] = x
        hd = kf.measurement_scale(x)
        for a in range(3):
            for b in range(3):
                ppos[k + 1, a, b] = P[a, b] * hd[a] * hd[b]
    hd = kf.measurement_scale(x0)
    for a in range(3):
        for b in range(3):
            ppos[0, a, b] = P0[a, b] * hd[a] * hd[b]
    return (states, fcs, wcs, qas, qgs, ppos, p_post, p_prior, dxs, comps, innov, s_diag,
            rejected)


@njit(cache=True)
def covariance_run(states, f, w, qa, qg, dt, ep_idx, valid, P0, sigma, off):
    """The matched filter's covariance along a given trajectory (no estimation): the same
    propagation and update as :func:`run` with the nominal ``states`` (N+1, 10), readings
    ``f``, ``w`` and densities ``qa``, ``qg`` (N, 3). Returns ppos (N+1, 3, 3) in metres,
    P_post, P_prior (M+1, n, n)."""
    n = P0.shape[0]
    N = f.shape[0]
    M = ep_idx.shape[0] - 1
    ppos = np.empty((N + 1, 3, 3))
    p_post = np.empty((M + 1, n, n))
    p_prior = np.empty((M + 1, n, n))
    P = P0.copy()
    p_post[0] = P
    p_prior[0] = P
    zero = np.zeros(3)
    e = 1
    for k in range(N):
        propagate(P, states[k], f[k], w[k], dt, qa[k], qg[k], off, EARTH_WGS84)
        if e <= M and ep_idx[e] == k + 1:
            p_prior[e] = P
            if valid[e - 1]:
                kf.gps_update(P, states[k + 1], states[k + 1, :3] + zero, sigma)
            p_post[e] = P
            e += 1
        hd = kf.measurement_scale(states[k + 1])
        for a in range(3):
            for b in range(3):
                ppos[k + 1, a, b] = P[a, b] * hd[a] * hd[b]
    hd = kf.measurement_scale(states[0])
    for a in range(3):
        for b in range(3):
            ppos[0, a, b] = P0[a, b] * hd[a] * hd[b]
    return ppos, p_post, p_prior


@njit(cache=True)
def interval_covariances(P_start, states, f, w, qa, qg, dt, k0, k1, off):
    """Recompute the covariances of samples k0..k1 from P at k0 (no fix in between), and
    the F of each step: (Pj (k1-k0+1, n, n), Fs (k1-k0, n, n))."""
    n = P_start.shape[0]
    s = k1 - k0
    Pj = np.empty((s + 1, n, n))
    Fs = np.empty((s, n, n))
    P = P_start.copy()
    Pj[0] = P
    for i in range(s):
        k = k0 + i
        Fs[i] = propagate(P, states[k], f[k], w[k], dt, qa[k], qg[k], off, EARTH_WGS84)
        Pj[i + 1] = P
    return Pj, Fs


def state_names(off: np.ndarray) -> list[str]:
    """Names of the state vector's entries for a layout."""
    names = ["dlat", "dlon", "dh", "dvN", "dvE", "dvD", "epsN", "epsE", "epsD"]
    short = {"accel_bias": "ba", "gyro_bias": "bg", "accel_scale": "sa", "gyro_scale": "sg"}
    for b, name in enumerate(BLOCKS):
        if off[b] >= 0:
            names += [f"{short[name]}{ax}" for ax in "xyz"]
    return names


def position_scale(states: np.ndarray) -> np.ndarray:
    """(N, 3) metres per unit of (dlat, dlon, dh): (R_M + h, (R_N + h) cos lat, 1)."""
    from navgate.nav.earth import radii_array

    rm, rn = radii_array(states[:, 0])
    h = states[:, 2]
    return np.column_stack([rm + h, (rn + h) * np.cos(states[:, 0]), np.ones_like(h)])


__all__ = ["BLOCKS", "layout", "run", "covariance_run", "interval_covariances",
           "error_dynamics", "propagate", "apply_correction", "compensate",
           "state_names", "position_scale"]
