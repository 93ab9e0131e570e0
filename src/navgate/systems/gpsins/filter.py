"""Seed 002's 9-state loosely coupled GPS/INS Kalman filter.

Reference: seed 002, "Kalman filter module" (after Shin 2001, Schmidt 1978, Bar-Itzhack
1988, Grewal 2001): state ``x = (d lat, d lon, d h, dv_N, dv_E, dv_D, eps_N, eps_E, eps_D)``,
errors defined as computed minus true (r_hat = r + dr, v_hat = v + dv,
C_hat = (I - E) C with E = [eps x]);

    F = [[F_rr, F_rv, 0], [F_vr, F_vv, (f^n x)], [F_er, F_ev, -((Omega + omega') x)]]
    G = [[0, 0], [C_b^n, 0], [0, -C_b^n]],  u = (df^b, dw_ib^b),  Q = diag(sa^2 x3, sw^2 x3)
    Phi = I + F dt,  Q_k = Phi G Q G' Phi' dt

and the GPS position measurement, rows scaled by (R + h) and (R + h) cos(lat):

    z = [(R_M+h)(lat_INS - lat_GPS), (R_N+h) cos(lat)(lon_INS - lon_GPS), h_INS - h_GPS]
    H = [diag(R_M+h, (R_N+h) cos lat, 1) | 0 | 0],  R = diag(20 m)^2.

The paper's blocks are checked against finite differences of the nonlinear INS
(tests/gpsins/test_error_model.py); the seed's typos found that way or by inspection, and
corrected here (docs/seed002-gpsins.md):

1. F's top-left block is printed F_rv; it is F_rr (the position rows are F_rr dr + F_rv dv).
2. E^n's bottom row is printed (-eps_E, -eps_N, 0); the skew matrix has (-eps_E, +eps_N, 0).
3. F_vr(E, h) is printed +vE vD/(R+h)^2 - vN vE tan(lat)/(R+h)^2; the derivative of
   v_E' = ... + vE vN tan/(R+h) + vE vD/(R+h) is -(vE vD + vN vE tan(lat))/(R+h)^2.
4. F's velocity-attitude block is printed (f^b x); with C_hat = (I - E) C it is (f^n x).
5. Eq. 25 prints +((Omega + omega') x) eps; F (and the derivation) has the minus sign.

The paper's single R_e becomes, term by term, the radius of the nonlinear equation the term
comes from (R_M in latitude rate and w_en,E, R_N in longitude rate and w_en,N/D); the height
derivative of gravity uses the paper's spherical law -2 g / (R + h) with R the Gaussian mean
radius sqrt(R_M R_N). Radius derivatives with latitude are neglected, as in the paper
("R_e is considered a constant"). Closed loop: after each update the estimate corrects the
INS (lat -= d lat, ..., C <- (I + [eps x]) C_hat as an exact rotation) and is reset to 0.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from navgate.nav.earth import OMEGA_IE
from navgate.systems.gpsins.ins import dcm_from_quat, earth_terms

NX = 9


@njit(cache=True)
def error_dynamics(x, f_b, kind):
    """F (9 x 9) at navigation state ``x`` with body specific force ``f_b``."""
    lat, h = x[0], x[2]
    vn, ve, vd = x[3], x[4], x[5]
    rm, rn, g = earth_terms(lat, h, kind)
    RM = rm + h
    RN = rn + h
    RG = math.sqrt(rm * rn) + h
    s = math.sin(lat)
    c = math.cos(lat)
    t = s / c
    W = OMEGA_IE
    F = np.zeros((NX, NX))
    # F_rr
    F[0, 2] = -vn / (RM * RM)
    F[1, 0] = ve * s / (RN * c * c)
    F[1, 2] = -ve / (RN * RN * c)
    # F_rv
    F[0, 3] = 1.0 / RM
    F[1, 4] = 1.0 / (RN * c)
    F[2, 5] = -1.0
    # F_vr
    F[3, 0] = -2.0 * ve * W * c - ve * ve / (RN * c * c)
    F[3, 2] = -vn * vd / (RM * RM) + ve * ve * t / (RN * RN)
    F[4, 0] = 2.0 * W * (vn * c - vd * s) + ve * vn / (RN * c * c)
    F[4, 2] = -(ve * vd + vn * ve * t) / (RN * RN)
    F[5, 0] = 2.0 * ve * W * s
    F[5, 2] = ve * ve / (RN * RN) + vn * vn / (RM * RM) - 2.0 * g / RG
    # F_vv
    F[3, 3] = vd / RM
    F[3, 4] = -2.0 * W * s - 2.0 * ve * t / RN
    F[3, 5] = vn / RM
    F[4, 3] = 2.0 * W * s + ve * t / RN
    F[4, 4] = (vd + vn * t) / RN
    F[4, 5] = 2.0 * W * c + ve / RN
    F[5, 3] = -2.0 * vn / RM
    F[5, 4] = -2.0 * W * c - 2.0 * ve / RN
    # (f^n x)
    C = dcm_from_quat(x[6], x[7], x[8], x[9])
    fn = C @ f_b
    F[3, 7] = -fn[2]
    F[3, 8] = fn[1]
    F[4, 6] = fn[2]
    F[4, 8] = -fn[0]
    F[5, 6] = -fn[1]
    F[5, 7] = fn[0]
    # F_er
    F[6, 0] = -W * s
    F[6, 2] = -ve / (RN * RN)
    F[7, 2] = vn / (RM * RM)
    F[8, 0] = -W * c - ve / (RN * c * c)
    F[8, 2] = ve * t / (RN * RN)
    # F_ev
    F[6, 4] = 1.0 / RN
    F[7, 3] = -1.0 / RM
    F[8, 4] = -t / RN
    # -(w_in x)
    wn = W * c + ve / RN
    we = -vn / RM
    wd = -W * s - ve * t / RN
    F[6, 7] = wd
    F[6, 8] = -we
    F[7, 6] = -wd
    F[7, 8] = wn
    F[8, 6] = we
    F[8, 7] = -wn
    return F


@njit(cache=True)
def noise_input(x):
    """G (9 x 6): [[0, 0], [C_b^n, 0], [0, -C_b^n]]."""
    C = dcm_from_quat(x[6], x[7], x[8], x[9])
    G = np.zeros((NX, 6))
    for i in range(3):
        for j in range(3):
            G[3 + i, j] = C[i, j]
            G[6 + i, 3 + j] = -C[i, j]
    return G


@njit(cache=True)
def propagate(P, x, f_b, dt, q_acc, q_gyro, kind):
    """P <- Phi P Phi' + Q_k with Phi = I + F dt, Q_k = Phi G Q G' Phi' dt (in place).

    ``q_acc``, ``q_gyro``: (3,) spectral densities of df^b and dw^b per body axis
    ((m/s^2)^2/Hz, (rad/s)^2/Hz). Since Phi P Phi' + Phi G Q G' Phi' dt = Phi (P + G Q G' dt)
    Phi', the noise is added first; G Q G' = blockdiag(0, C Qa C', C Qg C').
    """
    F = error_dynamics(x, f_b, kind)
    phi = np.eye(NX)
    for i in range(NX):
        for j in range(NX):
            phi[i, j] += F[i, j] * dt
    C = dcm_from_quat(x[6], x[7], x[8], x[9])
    for i in range(3):
        for j in range(3):
            a = 0.0
            w = 0.0
            for m in range(3):
                a += C[i, m] * q_acc[m] * C[j, m]
                w += C[i, m] * q_gyro[m] * C[j, m]
            P[3 + i, 3 + j] += a * dt
            P[6 + i, 6 + j] += w * dt
    tmp = np.zeros((NX, NX))
    for i in range(NX):
        for k in range(NX):
            a = phi[i, k]
            if a != 0.0:
                for j in range(NX):
                    tmp[i, j] += a * P[k, j]
    for i in range(NX):
        for j in range(i, NX):
            acc = 0.0
            for k in range(NX):
                acc += tmp[i, k] * phi[j, k]
            P[i, j] = acc
            P[j, i] = acc
    return phi


@njit(cache=True)
def measurement_scale(x):
    """Diagonal of H's position block: (R_M + h, (R_N + h) cos lat, 1) (WGS84 radii)."""
    rm, rn, _ = earth_terms(x[0], x[2], 0)
    return np.array([rm + x[2], (rn + x[2]) * math.cos(x[0]), 1.0])


@njit(cache=True)
def check_update_covariance(P, S):
    """A GPS update's covariances, checked once per fix (O(n), no factorisation): every
    variance on P's diagonal finite and >= 0 (a negative-definite P fails here), and the
    3 x 3 innovation covariance S = H P H' + R positive definite by its leading principal
    minors (Sylvester's criterion; an indefinite P that passes the diagonal can fail here).
    ValueError naming P otherwise: the update would divide by a meaningless S."""
    for i in range(P.shape[0]):
        if not P[i, i] >= 0.0:
            raise ValueError("P: covariance has a negative or non-finite variance on its "
                             "diagonal")
    m1 = S[0, 0]
    m2 = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    m3 = (S[0, 0] * (S[1, 1] * S[2, 2] - S[1, 2] * S[2, 1])
          - S[0, 1] * (S[1, 0] * S[2, 2] - S[1, 2] * S[2, 0])
          + S[0, 2] * (S[1, 0] * S[2, 1] - S[1, 1] * S[2, 0]))
    if not (m1 > 0.0 and m2 > 0.0 and m3 > 0.0):
        raise ValueError("P: the innovation covariance H P H' + R is not positive definite "
                         "(P is not a covariance)")


@njit(cache=True)
def gps_update(P, x, gps, sigma):
    """Kalman update with a GPS fix ``gps = (lat, lon, h)``; returns (dx, innovation z,
    innovation covariance S). Joseph form; P (n x n, the navigation block first: this filter's
    9 states or the augmented filter's) updated in place. A non-finite fix or a negative sigma
    raises ValueError (caught where it would enter the filter)."""
    for i in range(3):
        if not math.isfinite(gps[i]):
            raise ValueError("gps: the fix has a non-finite component")
        if not sigma[i] >= 0.0:
            raise ValueError("sigma: GPS sigmas must be non-negative")
    n = P.shape[0]
    hd = measurement_scale(x)
    z = np.empty(3)
    z[0] = hd[0] * (x[0] - gps[0])
    z[1] = hd[1] * (x[1] - gps[1])
    z[2] = x[2] - gps[2]
    PHt = np.empty((n, 3))
    for i in range(n):
        for j in range(3):
            PHt[i, j] = P[i, j] * hd[j]
    S = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            S[i, j] = hd[i] * PHt[i, j]
        S[i, i] += sigma[i] * sigma[i]
    check_update_covariance(P, S)
    # S^-1 by cofactors (3 x 3, symmetric positive definite)
    c00 = S[1, 1] * S[2, 2] - S[1, 2] * S[2, 1]
    c01 = S[0, 2] * S[2, 1] - S[0, 1] * S[2, 2]
    c02 = S[0, 1] * S[1, 2] - S[0, 2] * S[1, 1]
    c11 = S[0, 0] * S[2, 2] - S[0, 2] * S[2, 0]
    c12 = S[0, 2] * S[1, 0] - S[0, 0] * S[1, 2]
    c22 = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    det = S[0, 0] * c00 + S[0, 1] * (S[1, 2] * S[2, 0] - S[1, 0] * S[2, 2]) + S[0, 2] * (
        S[1, 0] * S[2, 1] - S[1, 1] * S[2, 0])
    Si = np.empty((3, 3))
    Si[0, 0], Si[0, 1], Si[0, 2] = c00 / det, c01 / det, c02 / det
    Si[1, 0], Si[1, 1], Si[1, 2] = c01 / det, c11 / det, c12 / det
    Si[2, 0], Si[2, 1], Si[2, 2] = c02 / det, c12 / det, c22 / det
    K = np.empty((n, 3))
    dx = np.empty(n)
    for i in range(n):
        for j in range(3):
            K[i, j] = PHt[i, 0] * Si[0, j] + PHt[i, 1] * Si[1, j] + PHt[i, 2] * Si[2, j]
        dx[i] = K[i, 0] * z[0] + K[i, 1] * z[1] + K[i, 2] * z[2]
    # X = (I - K H) P = P - K (H P), (H P)[m, j] = PHt[j, m];
    # P' = X (I - K H)' + K R K' = X - (X H') K' + K R K' (upper triangle, mirrored)
    X = np.empty((n, n))
    for i in range(n):
        k0, k1, k2 = K[i, 0], K[i, 1], K[i, 2]
        for j in range(n):
            X[i, j] = P[i, j] - k0 * PHt[j, 0] - k1 * PHt[j, 1] - k2 * PHt[j, 2]
    r0, r1, r2 = sigma[0] * sigma[0], sigma[1] * sigma[1], sigma[2] * sigma[2]
    for i in range(n):
        a0 = X[i, 0] * hd[0]
        a1 = X[i, 1] * hd[1]
        a2 = X[i, 2] * hd[2]
        b0, b1, b2 = K[i, 0] * r0, K[i, 1] * r1, K[i, 2] * r2
        for j in range(i, n):
            P[i, j] = (X[i, j] + (b0 - a0) * K[j, 0] + (b1 - a1) * K[j, 1]
                       + (b2 - a2) * K[j, 2])
    for i in range(n):
        for j in range(i):
            P[i, j] = P[j, i]
    return dx, z, S


@njit(cache=True)
def apply_correction(x, dx):
    """Closed-loop correction of the INS state by the error estimate (in place)."""
    x[0] -= dx[0]
    x[1] -= dx[1]
    x[2] -= dx[2]
    x[3] -= dx[3]
    x[4] -= dx[4]
    x[5] -= dx[5]
    # C = (I + [eps x]) C_hat, as the exact rotation exp([eps x]): q <- q_eps (x) q
    ex, ey, ez = dx[6], dx[7], dx[8]
    ang = math.sqrt(ex * ex + ey * ey + ez * ez)
    if ang < 1e-12:
        a0, s = 1.0, 0.5
    else:
        a0, s = math.cos(0.5 * ang), math.sin(0.5 * ang) / ang
    a1, a2, a3 = s * ex, s * ey, s * ez
    q0, q1, q2, q3 = x[6], x[7], x[8], x[9]
    r0 = a0 * q0 - a1 * q1 - a2 * q2 - a3 * q3
    r1 = a0 * q1 + a1 * q0 + a2 * q3 - a3 * q2
    r2 = a0 * q2 - a1 * q3 + a2 * q0 + a3 * q1
    r3 = a0 * q3 + a1 * q2 - a2 * q1 + a3 * q0
    n = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3)
    if not (n > 0.0 and n < math.inf):
        raise ValueError("x: the attitude quaternion x[6:10] is zero or not finite")
    x[6], x[7], x[8], x[9] = r0 / n, r1 / n, r2 / n, r3 / n
