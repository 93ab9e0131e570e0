"""15-state error-state Kalman filter for the strapdown INS (seed 000 "Covariance
Propagation" and "Kalman Update Engine").

Error state, in seed 000's order ``dx = [dp(3), dv(3), dtheta(3), db_a(3), db_g(3)]``:
position error (NED, m), velocity error (NED, m/s), attitude error (NED-resolved small
angles, rad), accelerometer and gyro bias errors (body axes). Sign convention (one
convention throughout; docs/decisions.md): every error is *estimated minus true*:
``p_est = p_true + dp``, ``C_est = (I + [dtheta x]) C_true``, ``b_est = b_true + db``.

Continuous dynamics (Groves 2013, sec. 14.2, in this sign convention):

    dp'     = dv
    dv'     = -[f_n x] dtheta - C_b^n db_a - [(2 w_ie + w_en) x] dv + (2 g / R) dp_D e_D
    dtheta' = -[w_in x] dtheta - C_b^n db_g
    db'     = -db / tau   (first-order Gauss-Markov bias states)

The bias *estimates* are held constant between updates: the sensor's bias is a random
constant (turn-on) plus a slow in-run wander, and only the covariance of the estimation
error follows the Gauss-Markov model. Decaying the estimate as the Gauss-Markov mean
would pull a constant turn-on bias (0.05 deg/s for an ADIS16500-class gyro) toward zero at
rate 1/tau, an error the covariance does not describe (docs/decisions.md).

The velocity/attitude coupling is -[f_n x] (the specific force in NED), not seed 000's
-[g x]: the two agree only in level unaccelerated flight (seeds README). The accelerometer
bias enters through -C_b^n (seed 000 shows +C_b^n, which would need db = true - estimated;
with one convention for all states both bias couplings carry the minus sign).

Discrete propagation each IMU sample: Phi = I + F dt (bias blocks exp(-dt/tau), as
seed 000's D), P <- Phi P Phi' + Q_d, where only the 60 structurally non-zero entries of
Phi are touched (seed 000's "sparse Phi": 9 of 25 blocks), and only the upper triangle of
P is computed and mirrored, so P stays exactly symmetric (seed 000 stores those 120
elements). Q_d = diag(0, VRW^2 dt, ARW^2 dt, sigma_ba^2 (1 - e^(-2dt/tau_a)),
sigma_bg^2 (1 - e^(-2dt/tau_g))): white noise that is isotropic in body axes stays
isotropic after rotation by C_b^n.

Measurement updates (:meth:`ErrorStateFilter.update`): innovation y = h(x_est) - z so that
y = H dx + v; S = H P H' + R; chi-square gate on y' S^-1 y (rejected updates are counted
and not applied); K = P H' S^-1 (the 2x2 inverse by the direct formula, seed 000);
P <- (I - K H) P (I - K H)' + K R K' (Joseph form); dx = K y is fed back into the INS
(closed loop: p -= dp, v -= dv, q <- q(-dtheta) (x) q, b -= db) and the error state is
reset to zero. For the 2-D TRN fix H = [I2 0] and z is the fix (north, east); seed 000
forms z = trn - ins and subtracts K z, which is the same thing with y = ins - trn.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from navgate.nav import strapdown
from navgate.nav.earth import E2, A
from navgate.nav.rotations import quat_from_rotvec, quat_multiply

N_STATES = 15
POS, VEL, ATT, BA, BG = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)

# structural non-zeros of Phi, row by row (seed 000 "Sparse Phi Optimization")
_PATTERN = [[0, 3], [1, 4], [2, 5]]
_PATTERN += [[2, 3, 4, 5, 6, 7, 8, 9, 10, 11]] * 3
_PATTERN += [[6, 7, 8, 12, 13, 14]] * 3
_PATTERN += [[9], [10], [11], [12], [13], [14]]
PHI_NNZ = np.array([len(r) for r in _PATTERN], dtype=np.int64)
PHI_COLS = np.full((N_STATES, 10), -1, dtype=np.int64)
for _i, _r in enumerate(_PATTERN):
    PHI_COLS[_i, : len(_r)] = _r


@dataclass(frozen=True)
class FilterConfig:
    """Process-noise model of the error-state filter (from the IMU's specification)."""

    accel_vrw: float  #: m/s/sqrt(s)
    gyro_arw: float  #: rad/sqrt(s)
    accel_bias_sigma: float  #: m/s^2, steady-state sigma of the Gauss-Markov bias
    accel_bias_tau: float  #: s
    gyro_bias_sigma: float  #: rad/s
    gyro_bias_tau: float  #: s
    gate_probability: float = 0.999  #: chi-square gate; innovations beyond are rejected

    def __post_init__(self):
        from navgate.nav import validate

        for name in ("accel_vrw", "gyro_arw", "accel_bias_sigma", "gyro_bias_sigma"):
            validate.non_negative(name, getattr(self, name))
        # tau = 0 divides dt by zero in exp(-dt / tau); a correlation time must be positive
        for name in ("accel_bias_tau", "gyro_bias_tau"):
            validate.positive(name, getattr(self, name))
        validate.probability("gate_probability", self.gate_probability)

    @classmethod
    def from_imu_spec(cls, spec, *, rate_hz=400.0, residual_accel_bias=0.0,
                      residual_gyro_bias=0.0, tau=3600.0, floor_scale=1.0, **kw):
        """Noise from an ImuSpec. Quantisation adds LSB^2/12 per sample to the white noise,
        i.e. a random-walk density of LSB sqrt(dt / 12) at the IMU rate."""
        from navgate.nav import validate

        quant_g = spec.gyro_lsb**2 / 12.0 if spec.quantize else 0.0
        quant_a = spec.accel_lsb**2 / 12.0 if spec.quantize else 0.0
        dt = 1.0 / validate.positive("rate_hz", rate_hz)
        arw = math.sqrt(spec.gyro_arw**2 + quant_g * dt) * floor_scale
        vrw = math.sqrt(spec.accel_vrw**2 + quant_a * dt) * floor_scale
        bg = math.sqrt(spec.gyro_bias_instability**2 + residual_gyro_bias**2)
        ba = math.sqrt(spec.accel_bias_instability**2 + residual_accel_bias**2)
        return cls(vrw, arw, max(ba, 1e-9), tau, max(bg, 1e-12), tau, **kw)


@njit(cache=True)
def _build_phi(phi, c, f_n, lat, h, vn, ve, dt, decay_a, decay_g):
    """Write the non-zero entries of Phi = I + F dt for the current navigation state."""
    s = math.sin(lat)
    cl = math.cos(lat)
    d = 1.0 - E2 * s * s
    re = A / math.sqrt(d)
    rn = re * (1.0 - E2) / d
    wie_n = 7.292115e-5 * cl
    wie_d = -7.292115e-5 * s
    wen_n = ve / (re + h)
    wen_e = -vn / (rn + h)
    wen_d = -ve * (s / cl) / (re + h)
    g = 9.80665
    r0 = math.sqrt(rn * re) + h
    for i in range(3):
        phi[i, i] = 1.0
        phi[i, 3 + i] = dt
    # velocity rows
    wx = 2.0 * wie_n + wen_n
    wy = wen_e
    wz = 2.0 * wie_d + wen_d
    phi[3, 3] = 1.0
    phi[3, 4] = wz * dt
    phi[3, 5] = -wy * dt
    phi[4, 3] = -wz * dt
    phi[4, 4] = 1.0
    phi[4, 5] = wx * dt
    phi[5, 3] = wy * dt
    phi[5, 4] = -wx * dt
    phi[5, 5] = 1.0
    phi[5, 2] = 2.0 * g / r0 * dt
    # -[f_n x] dt
    phi[3, 6] = 0.0
    phi[3, 7] = f_n[2] * dt
    phi[3, 8] = -f_n[1] * dt
    phi[4, 6] = -f_n[2] * dt
    phi[4, 7] = 0.0
    phi[4, 8] = f_n[0] * dt
    phi[5, 6] = f_n[1] * dt
    phi[5, 7] = -f_n[0] * dt
    phi[5, 8] = 0.0
    # attitude rows: I - [w_in x] dt
    ix = wie_n + wen_n
    iy = wen_e
    iz = wie_d + wen_d
    phi[6, 6] = 1.0
    phi[6, 7] = iz * dt
    phi[6, 8] = -iy * dt
    phi[7, 6] = -iz * dt
    phi[7, 7] = 1.0
    phi[7, 8] = ix * dt
    phi[8, 6] = iy * dt
    phi[8, 7] = -ix * dt
    phi[8, 8] = 1.0
    for i in range(3):
        for j in range(3):
            phi[3 + i, 9 + j] = -c[i, j] * dt
            phi[6 + i, 12 + j] = -c[i, j] * dt
        phi[9 + i, 9 + i] = decay_a
        phi[12 + i, 12 + i] = decay_g


#: P's rows padded to this many doubles inside the compiled loops (two 8-double vectors)
PAD = 16
#: the compiled loops' work space: P (PAD x PAD, row-major), then B, then B' (offsets)
_P, _B, _BT = 0, PAD * PAD, 2 * PAD * PAD
WS_SIZE = 3 * PAD * PAD


@njit(cache=True)
def propagate_covariance(p, phi, work, q_diag):
    """P <- Phi P Phi' + diag(q_diag) on a 15x15 P, using Phi's sparsity; P stays exactly
    symmetric. (One step; the filter's loops use :func:`_cov_step` on their work space.)"""
    ws = np.zeros(WS_SIZE)
    pp = ws[:PAD * PAD].reshape((PAD, PAD))
    pp[:N_STATES, :N_STATES] = p
    _cov_step(ws, phi, q_diag)
    p[:, :] = pp[:N_STATES, :N_STATES]


@njit(cache=True, inline="always")
def _phi_rows(ws, o, x, c):
    """ws rows at ``o`` <- Phi times the PAD-wide rows at ``x`` (row stride PAD).

    Row i of the result is sum_k Phi_ik X_k over Phi's structural non-zeros (PHI_COLS, in
    that order): multiply-adds of whole padded rows. The loop runs over the columns with the
    60 coefficients held in registers (tuples), so the compiler vectorises it across the
    16 columns; the offsets are constants, so it can prove the rows it writes are not the
    rows it reads.
    """
    r0, r1, r2 = (c[0, 0], c[0, 3]), (c[1, 1], c[1, 4]), (c[2, 2], c[2, 5])
    r3 = (c[3, 2], c[3, 3], c[3, 4], c[3, 5], c[3, 6], c[3, 7], c[3, 8], c[3, 9], c[3, 10],
          c[3, 11])
    r4 = (c[4, 2], c[4, 3], c[4, 4], c[4, 5], c[4, 6], c[4, 7], c[4, 8], c[4, 9], c[4, 10],
          c[4, 11])
    r5 = (c[5, 2], c[5, 3], c[5, 4], c[5, 5], c[5, 6], c[5, 7], c[5, 8], c[5, 9], c[5, 10],
          c[5, 11])
    r6 = (c[6, 6], c[6, 7], c[6, 8], c[6, 12], c[6, 13], c[6, 14])
    r7 = (c[7, 6], c[7, 7], c[7, 8], c[7, 12], c[7, 13], c[7, 14])
    r8 = (c[8, 6], c[8, 7], c[8, 8], c[8, 12], c[8, 13], c[8, 14])
    d = (c[9, 9], c[10, 10], c[11, 11], c[12, 12], c[13, 13], c[14, 14])
    for j in range(PAD):
        x0, x1, x2, x3 = ws[x + j], ws[x + 16 + j], ws[x + 32 + j], ws[x + 48 + j]
        x4, x5, x6, x7 = ws[x + 64 + j], ws[x + 80 + j], ws[x + 96 + j], ws[x + 112 + j]
        x8, x9, x10, x11 = ws[x + 128 + j], ws[x + 144 + j], ws[x + 160 + j], ws[x + 176 + j]
        x12, x13, x14 = ws[x + 192 + j], ws[x + 208 + j], ws[x + 224 + j]
        ws[o + j] = r0[0] * x0 + r0[1] * x3
        ws[o + 16 + j] = r1[0] * x1 + r1[1] * x4
        ws[o + 32 + j] = r2[0] * x2 + r2[1] * x5
        ws[o + 48 + j] = (r3[0] * x2 + r3[1] * x3 + r3[2] * x4 + r3[3] * x5 + r3[4] * x6
                          + r3[5] * x7 + r3[6] * x8 + r3[7] * x9 + r3[8] * x10 + r3[9] * x11)
        ws[o + 64 + j] = (r4[0] * x2 + r4[1] * x3 + r4[2] * x4 + r4[3] * x5 + r4[4] * x6
                          + r4[5] * x7 + r4[6] * x8 + r4[7] * x9 + r4[8] * x10 + r4[9] * x11)
        ws[o + 80 + j] = (r5[0] * x2 + r5[1] * x3 + r5[2] * x4 + r5[3] * x5 + r5[4] * x6
                          + r5[5] * x7 + r5[6] * x8 + r5[7] * x9 + r5[8] * x10 + r5[9] * x11)
        ws[o + 96 + j] = (r6[0] * x6 + r6[1] * x7 + r6[2] * x8 + r6[3] * x12 + r6[4] * x13
                          + r6[5] * x14)
        ws[o + 112 + j] = (r7[0] * x6 + r7[1] * x7 + r7[2] * x8 + r7[3] * x12 + r7[4] * x13
                           + r7[5] * x14)
        ws[o + 128 + j] = (r8[0] * x6 + r8[1] * x7 + r8[2] * x8 + r8[3] * x12 + r8[4] * x13
                           + r8[5] * x14)
        ws[o + 144 + j] = d[0] * x9
        ws[o + 160 + j] = d[1] * x10
        ws[o + 176 + j] = d[2] * x11
        ws[o + 192 + j] = d[3] * x12
        ws[o + 208 + j] = d[4] * x13
        ws[o + 224 + j] = d[5] * x14


@njit(cache=True, inline="always")
def _cov_step(ws, phi, q_diag):
    """One covariance step, P <- Phi P Phi' + Q, in the work space ``ws`` (WS_SIZE doubles:
    P padded to PAD x PAD at _P, the padding zero; B at _B; B' at _BT).

    B = Phi P is formed as multiply-adds of P's padded rows (:func:`_phi_rows`); its
    transpose gives Phi B' = Phi P Phi' the same way. Entry (j, i) of that product is
    sum_k Phi_jk B_ik over Phi's row j in PHI_COLS order, the terms and order of the scalar
    form B_i . Phi_j (seed 000's sparse Phi), so the result equals it bit for bit. Only the
    upper triangle is taken (plus Q's diagonal) and mirrored: P stays exactly symmetric.
    """
    _phi_rows(ws, _B, _P, phi)
    for i in range(N_STATES):
        for j in range(N_STATES):
            ws[_BT + j * PAD + i] = ws[_B + i * PAD + j]
    _phi_rows(ws, _B, _BT, phi)  # row j of Phi B' holds P_new[i, j] at column i
    for i in range(N_STATES):
        ws[_P + i * (PAD + 1)] = ws[_B + i * (PAD + 1)] + q_diag[i]
        for j in range(i + 1, N_STATES):
            v = ws[_B + j * PAD + i]
            ws[_P + i * PAD + j] = v
            ws[_P + j * PAD + i] = v


@njit(cache=True, inline="always")
def _imu_step(nav, bias_a, bias_g, ws, last_good, gx, gy, gz, ax, ay, az, dt, q_diag,
              decay_a, decay_g, propagate_p, w, f, c_old, c_new, f_n, phi):
    """One IMU sample: hold a non-finite reading, remove the bias estimates, mechanize,
    propagate P. Returns 1 for a held (non-finite) reading, else 0."""
    bad = 0
    if (math.isfinite(gx) and math.isfinite(gy) and math.isfinite(gz) and math.isfinite(ax)
            and math.isfinite(ay) and math.isfinite(az)):
        last_good[0] = gx
        last_good[1] = gy
        last_good[2] = gz
        last_good[3] = ax
        last_good[4] = ay
        last_good[5] = az
    else:
        bad = 1
    for i in range(3):
        w[i] = last_good[i] - bias_g[i]
        f[i] = last_good[3 + i] - bias_a[i]
    lat, h, vn, ve = nav[0], nav[2], nav[3], nav[4]
    strapdown.mechanize_step(nav, w, f, dt, c_old, c_new, f_n)
    if propagate_p:
        _build_phi(phi, c_old, f_n, lat, h, vn, ve, dt, decay_a, decay_g)
        _cov_step(ws, phi, q_diag)
    return bad


@njit(cache=True)
def run_propagation(nav, bias_a, bias_g, p, gyro, accel, k0, k1, dt, q_diag,
                    decay_a, decay_g, propagate_p, out_nav, out_sigma, out_every, out_offset,
                    last_good):
    """Mechanize and propagate P over samples k0..k1-1 (the filter's inner loop).

    gyro/accel are calibrated readings; the bias estimates are removed here. A reading with
    a non-finite component is not used: the last good reading (``last_good``, 6 values,
    updated in place) is held instead, and the number of such samples is returned, so a bad
    sample is counted and flagged rather than turned into NaN states. Every ``out_every``
    samples (global index multiple) the navigation state and the square roots of P's
    diagonal are logged at row (k + 1 - out_offset) // out_every.
    """
    c_old = np.empty((3, 3))
    c_new = np.empty((3, 3))
    f_n = np.empty(3)
    phi = np.zeros((15, 15))
    ws = np.zeros(WS_SIZE)
    pp = ws[:PAD * PAD].reshape((PAD, PAD))
    pp[:N_STATES, :N_STATES] = p
    w = np.empty(3)
    f = np.empty(3)
    bad = 0
    for k in range(k0, k1):
        bad += _imu_step(nav, bias_a, bias_g, ws, last_good, gyro[k, 0], gyro[k, 1],
                         gyro[k, 2], accel[k, 0], accel[k, 1], accel[k, 2], dt, q_diag,
                         decay_a, decay_g, propagate_p, w, f, c_old, c_new, f_n, phi)
        if (k + 1) % out_every == 0:
            row = (k + 1 - out_offset) // out_every
            if 0 <= row < out_nav.shape[0]:
                out_nav[row] = nav
                for i in range(15):
                    out_sigma[row, i] = math.sqrt(max(pp[i, i], 0.0))
    p[:, :] = pp[:N_STATES, :N_STATES]
    return bad


def _readings(name, value):
    """An (N, 3) array (the compiled loop indexes [k, 0..2]); an ndarray is passed on as it
    is (no copy: callers hand the whole flight's readings with a k0..k1 window each call)."""
    a = value if isinstance(value, np.ndarray) else np.asarray(value, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name}: expected an N x 3 array, got shape {a.shape}")
    return a


@njit(cache=True, inline="always")
def _calibrated(words, k, lsb, bias, m, out):
    """Seed 000's calibration of sample k: out_i = (w * lsb - b) . M_i, the three products
    summed left to right (the float64 reference's fixed order)."""
    x0 = float(words[k, 0]) * lsb - bias[0]
    x1 = float(words[k, 1]) * lsb - bias[1]
    x2 = float(words[k, 2]) * lsb - bias[2]
    for i in range(3):
        out[i] = x0 * m[i, 0] + x1 * m[i, 1] + x2 * m[i, 2]


@njit(cache=True)
def _correct(nav, bias_a, bias_g, dx):
    """Closed-loop feedback of dx (compiled :meth:`ErrorStateFilter.apply_correction`)."""
    rn, re = strapdown._frame_terms(nav[0], nav[2], nav[3], nav[4])[:2]
    nav[0] -= dx[0] / (rn + nav[2])
    nav[1] -= dx[1] / ((re + nav[2]) * math.cos(nav[0]))
    nav[2] += dx[2]
    for i in range(3):
        nav[3 + i] -= dx[3 + i]
    dq = quat_from_rotvec(-dx[6:9])
    q = quat_multiply(dq, nav[6:10])
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    for i in range(4):
        nav[6 + i] = q[i] / norm
    for i in range(3):
        bias_a[i] -= dx[9 + i]
        bias_g[i] -= dx[12 + i]


#: status of the compiled scalar update
UPD_ACCEPTED, UPD_REJECTED, UPD_NONFINITE, UPD_NOT_POSITIVE = 0, 1, 2, 3


@njit(cache=True)
def update_scalar(p, nav, bias_a, bias_g, m, y, r, gate, dx):
    """Gated Joseph-form update with one measurement of state ``m`` (H = e_m), compiled.

    ``p`` is P (15x15, or the padded PAD x PAD storage); y = h(x_est) - z, r = its variance.
    S = P_mm + r, NIS = y^2 / S; beyond ``gate`` the update is rejected (nothing changes).
    Otherwise K = P e_m / S and P <- (I - K e_m') P (I - K e_m')' + K r K', which for this H
    is P_ij - K_i P_mj - P_im K_j + K_i K_j (P_mm + r); the upper triangle is formed and
    mirrored. dx = K y is written to ``dx`` and fed back (:func:`_correct`).
    Returns (status, nis): UPD_ACCEPTED / UPD_REJECTED, or UPD_NONFINITE / UPD_NOT_POSITIVE
    (nothing changed; the caller raises).
    """
    if not (math.isfinite(y) and math.isfinite(r)):
        return UPD_NONFINITE, math.nan
    s = p[m, m] + r
    if not s > 0.0:
        return UPD_NOT_POSITIVE, math.nan
    s_inv = 1.0 / s
    nis = y * s_inv * y
    if not nis <= gate:
        for i in range(N_STATES):
            dx[i] = 0.0
        return UPD_REJECTED, nis
    k = np.empty(N_STATES)
    pm = np.empty(N_STATES)
    for i in range(N_STATES):
        k[i] = p[i, m] * s_inv
        pm[i] = p[m, i]
    for i in range(N_STATES):
        for j in range(i, N_STATES):
            v = p[i, j] - k[i] * pm[j] - pm[i] * k[j] + k[i] * k[j] * s
            p[i, j] = v
            p[j, i] = v
    for i in range(N_STATES):
        dx[i] = k[i] * y
    _correct(nav, bias_a, bias_g, dx)
    return UPD_ACCEPTED, nis


#: counters of :func:`run_records` (an int64 array the caller keeps between calls)
(C_SAMPLES, C_IMU_BAD, C_BARO_ACC, C_BARO_REJ, C_BARO_INVALID, C_LOGGED, C_HAVE_GOOD,
 C_ERROR, C_ERROR_RECORD) = range(9)
N_COUNTERS = 9


@njit(cache=True)
def run_records(nav, bias_a, bias_g, p, last_good, kinds, index, m0, m1, gyro_words,
                accel_words, lsb, cal_bias, cal_m, baro_alt, baro_status, baro_r, gate1, dt,
                q_diag, decay_a, decay_g, propagate_p, log_every, out_nav, out_sigma, out_pne,
                counts, h_baro):
    """Records m0..m1-1 of a record stream in one call: IMU words (kind 0) through
    calibration, mechanization and covariance propagation; barometer records (kind 1)
    through the gated scalar update of the height (state 2); other kinds are skipped.

    Calibration: ``lsb`` (2,), ``cal_bias`` (2, 3), ``cal_m`` (2, 3, 3), gyro first.
    Before an IMU sample whose global count (``counts[C_SAMPLES]``) is a multiple of
    ``log_every`` and not yet logged, the state, sqrt(diag P) and P_NE are written at row
    ``counts[C_LOGGED]`` of the out arrays. A barometer record with status != 0 or a
    non-finite altitude is counted invalid and not applied; ``h_baro[0]`` is the newest
    barometer altitude (NaN after an invalid one). An update that cannot be formed stops the
    run with its status in ``counts[C_ERROR]`` and the record in ``counts[C_ERROR_RECORD]``.
    """
    c_old = np.empty((3, 3))
    c_new = np.empty((3, 3))
    f_n = np.empty(3)
    phi = np.zeros((15, 15))
    ws = np.zeros(WS_SIZE)
    pp = ws[:PAD * PAD].reshape((PAD, PAD))
    pp[:N_STATES, :N_STATES] = p
    w = np.empty(3)
    f = np.empty(3)
    g = np.empty(3)
    a = np.empty(3)
    dx = np.empty(N_STATES)
    for mi in range(m0, m1):
        kind = kinds[mi]
        i = index[mi]
        if kind == 0:
            n = counts[C_SAMPLES]
            if n % log_every == 0 and counts[C_LOGGED] == n // log_every:
                row = counts[C_LOGGED]
                if row < out_nav.shape[0]:
                    for j in range(10):
                        out_nav[row, j] = nav[j]
                    for j in range(N_STATES):
                        out_sigma[row, j] = math.sqrt(max(pp[j, j], 0.0))
                    out_pne[row] = pp[0, 1]
                    counts[C_LOGGED] = row + 1
            if counts[C_HAVE_GOOD] == 0:
                # seed the hold value with the first finite reading ahead in this stretch
                for mj in range(mi, m1):
                    if kinds[mj] == 0:
                        _calibrated(gyro_words, index[mj], lsb[0], cal_bias[0], cal_m[0], g)
                        _calibrated(accel_words, index[mj], lsb[1], cal_bias[1], cal_m[1], a)
                        ok = True
                        for j in range(3):
                            if not (math.isfinite(g[j]) and math.isfinite(a[j])):
                                ok = False
                        if ok:
                            for j in range(3):
                                last_good[j] = g[j]
                                last_good[3 + j] = a[j]
                            counts[C_HAVE_GOOD] = 1
                            break
            _calibrated(gyro_words, i, lsb[0], cal_bias[0], cal_m[0], g)
            _calibrated(accel_words, i, lsb[1], cal_bias[1], cal_m[1], a)
            counts[C_IMU_BAD] += _imu_step(nav, bias_a, bias_g, ws, last_good, g[0], g[1], g[2],
                                           a[0], a[1], a[2], dt, q_diag, decay_a, decay_g,
                                           propagate_p, w, f, c_old, c_new, f_n, phi)
            counts[C_SAMPLES] = n + 1
        elif kind == 1:
            h = baro_alt[i]
            if baro_status[i] != 0 or not math.isfinite(h):
                h_baro[0] = math.nan
                counts[C_BARO_INVALID] += 1
                continue
            h_baro[0] = h
            status, _ = update_scalar(pp, nav, bias_a, bias_g, 2, h - nav[2], baro_r, gate1,
                                      dx)
            if status == UPD_ACCEPTED:
                counts[C_BARO_ACC] += 1
            elif status == UPD_REJECTED:
                counts[C_BARO_REJ] += 1
            else:
                counts[C_ERROR] = status
                counts[C_ERROR_RECORD] = mi
                break
    p[:, :] = pp[:N_STATES, :N_STATES]


@functools.lru_cache(maxsize=64)
def chi2_gate(probability: float, dof: int) -> float:
    """Chi-square gate: the ``probability`` quantile with ``dof`` degrees of freedom.

    Cached per (probability, dof): the value depends on the configuration only, and
    ``scipy.stats.chi2.ppf`` was 57 % of each barometer update's cost (issue 32). It is
    ``2 gammaincinv(dof / 2, probability)``, exactly what ``chi2.ppf`` evaluates, taken
    from ``scipy.special`` because importing ``scipy.stats`` costs about a second.
    """
    from scipy.special import gammaincinv

    return float(2.0 * gammaincinv(dof / 2.0, probability))


@dataclass
class UpdateResult:
    accepted: bool
    nis: float  #: normalised innovation squared y' S^-1 y
    gate: float
    correction: np.ndarray  #: dx applied (zeros when rejected)


class ErrorStateFilter:
    """Closed-loop INS + 15-state error-state Kalman filter (float64 reference model)."""

    def __init__(self, nav0, p0, config: FilterConfig, *, rate_hz: float = 400.0,
                 bias_a0=None, bias_g0=None):
        from navgate.nav import validate

        self.nav = np.array(nav0, dtype=float)
        if self.nav.shape != (strapdown.NAV_SIZE,):
            raise ValueError("nav0 must be [lat, lon, h, vN, vE, vD, q0, q1, q2, q3]")
        validate.finite_array("nav0", self.nav)
        validate.nav_latitude("nav0[0] (latitude)", self.nav[0])
        validate.height_m("nav0[2] (height)", self.nav[2])
        validate.unit_quaternion("nav0[6:10] (attitude quaternion)", self.nav[6:10])
        self.p = np.array(validate.covariance("p0", p0, N_STATES), dtype=float)
        self.p = 0.5 * (self.p + self.p.T)
        self.config = config
        self.dt = 1.0 / validate.positive("rate_hz", rate_hz)
        self.bias_a = (np.zeros(3) if bias_a0 is None
                       else np.array(validate.finite_array("bias_a0", bias_a0, (3,))))
        self.bias_g = (np.zeros(3) if bias_g0 is None
                       else np.array(validate.finite_array("bias_g0", bias_g0, (3,))))
        if not isinstance(config, FilterConfig):
            raise ValueError(f"config: expected a FilterConfig, got {type(config).__name__}")
        c = config
        self.decay_a = math.exp(-self.dt / c.accel_bias_tau)
        self.decay_g = math.exp(-self.dt / c.gyro_bias_tau)
        self.q_diag = np.zeros(N_STATES)
        self.q_diag[VEL] = c.accel_vrw**2 * self.dt
        self.q_diag[ATT] = c.gyro_arw**2 * self.dt
        self.q_diag[BA] = c.accel_bias_sigma**2 * (1.0 - self.decay_a**2)
        self.q_diag[BG] = c.gyro_bias_sigma**2 * (1.0 - self.decay_g**2)
        #: the 1-degree-of-freedom chi-square gate (computed once per configuration)
        self.gate1 = chi2_gate(c.gate_probability, 1)
        self.accepted = {}
        self.rejected = {}
        #: the last finite IMU reading (gyro, accel), held over non-finite samples
        self.last_good = np.zeros(6)
        self._have_good = False
        #: IMU samples with a NaN/inf component (replaced by the previous good reading)
        self.imu_samples_rejected = 0

    def propagate(self, gyro, accel, k0, k1, *, propagate_p=True, out_nav=None, out_sigma=None,
                  out_every=1, out_offset=0):
        """Run samples k0..k1-1 of the calibrated readings through INS and covariance.

        ``gyro``/``accel`` are (N, 3) arrays (NaN/inf samples are held and counted, see
        :func:`run_propagation`); shapes and the range 0 <= k0 <= k1 <= N are checked here,
        once per call, because the compiled loop does not bounds-check its reads."""
        gyro = _readings("gyro", gyro)
        accel = _readings("accel", accel)
        if accel.shape != gyro.shape:
            raise ValueError(f"accel: shape {accel.shape} differs from gyro's {gyro.shape}")
        if not (isinstance(k0, (int, np.integer)) and isinstance(k1, (int, np.integer))
                and 0 <= k0 <= k1 <= gyro.shape[0]):
            raise ValueError(f"k0, k1: need integers 0 <= k0 <= k1 <= {gyro.shape[0]}, got "
                             f"{k0!r}, {k1!r}")
        if out_nav is None:
            out_nav = np.empty((0, strapdown.NAV_SIZE))
            out_sigma = np.empty((0, N_STATES))
        elif (np.ndim(out_nav) != 2 or np.shape(out_nav)[1] != strapdown.NAV_SIZE
              or out_sigma is None or np.shape(out_sigma) != (np.shape(out_nav)[0], N_STATES)):
            raise ValueError(f"out_nav, out_sigma: expected (M, {strapdown.NAV_SIZE}) and "
                             f"(M, {N_STATES}) arrays")
        if not (isinstance(out_every, (int, np.integer)) and out_every >= 1):
            raise ValueError(f"out_every: must be an integer >= 1, got {out_every!r}")
        if not self._have_good and k1 > k0:
            # seed the hold value with the first finite reading (or a level, resting IMU)
            ok = np.flatnonzero(np.all(np.isfinite(gyro[k0:k1]) & np.isfinite(accel[k0:k1]),
                                       axis=1))
            if ok.size:
                self.last_good[:3] = gyro[k0 + ok[0]]
                self.last_good[3:] = accel[k0 + ok[0]]
                self._have_good = True
        self.imu_samples_rejected += run_propagation(
            self.nav, self.bias_a, self.bias_g, self.p, gyro, accel, k0, k1, self.dt,
            self.q_diag, self.decay_a, self.decay_g, propagate_p, out_nav, out_sigma,
            out_every, out_offset, self.last_good)

    # -- measurement updates ----------------------------------------------------------------
    def update(self, y, h_matrix, r_matrix, kind: str) -> UpdateResult:
        """Generic gated Joseph-form update with innovation y = h(x_est) - z = H dx + v.

        ``y`` (m,), ``h_matrix`` (m, 15) finite, ``r_matrix`` an m x m symmetric positive
        semi-definite covariance (ValueError naming the argument otherwise: a negative or
        indefinite R would make S, the NIS and the Joseph update meaningless)."""
        from navgate.nav import validate

        y = np.atleast_1d(validate.finite_array("y", y))
        if y.ndim != 1:
            raise ValueError(f"y: expected an innovation vector, got shape {y.shape}")
        m = y.size
        h_matrix = np.atleast_2d(validate.finite_array("h_matrix", h_matrix))
        if h_matrix.shape != (m, N_STATES):
            raise ValueError(f"h_matrix: expected shape ({m}, {N_STATES}), got "
                             f"{h_matrix.shape}")
        r_matrix = validate.covariance("r_matrix", np.atleast_2d(np.asarray(r_matrix, float)),
                                       m)
        return self._update(y, h_matrix, r_matrix, kind)

    def _update(self, y, h_matrix, r_matrix, kind: str) -> UpdateResult:
        """:meth:`update` on arguments already checked (float arrays of the right shapes)."""
        m = y.size
        p = self.p
        pht = p @ h_matrix.T
        s = h_matrix @ pht + r_matrix
        if m == 1:
            if not s[0, 0] > 0:
                raise np.linalg.LinAlgError(f"{kind} update: innovation variance not positive")
            s_inv = np.array([[1.0 / s[0, 0]]])
        elif m == 2:
            det = s[0, 0] * s[1, 1] - s[0, 1] * s[1, 0]
            if not det > 1e-300 * max(1.0, abs(s[0, 0] * s[1, 1])):
                raise np.linalg.LinAlgError(f"{kind} update: singular innovation covariance")
            # seed 000 "2x2 Matrix Inverse (direct formula)"
            s_inv = np.array([[s[1, 1], -s[0, 1]], [-s[1, 0], s[0, 0]]]) / det
        else:
            s_inv = np.linalg.inv(s)
        nis = float(y @ s_inv @ y)
        gate = chi2_gate(self.config.gate_probability, m)
        if not nis <= gate:
            self.rejected[kind] = self.rejected.get(kind, 0) + 1
            return UpdateResult(False, nis, gate, np.zeros(N_STATES))
        k = pht @ s_inv
        ikh = np.eye(N_STATES) - k @ h_matrix
        p_new = ikh @ p @ ikh.T + k @ r_matrix @ k.T
        self.p = 0.5 * (p_new + p_new.T)
        dx = k @ y
        self.apply_correction(dx)
        self.accepted[kind] = self.accepted.get(kind, 0) + 1
        return UpdateResult(True, nis, gate, dx)

    def apply_correction(self, dx):
        """Closed-loop feedback of an error-state estimate, then the error state is zero."""
        nav = self.nav
        rn, re = strapdown._frame_terms(nav[0], nav[2], nav[3], nav[4])[:2]
        nav[0] -= dx[0] / (rn + nav[2])
        nav[1] -= dx[1] / ((re + nav[2]) * math.cos(nav[0]))
        nav[2] += dx[2]
        nav[3:6] -= dx[VEL]
        dq = quat_from_rotvec(-np.asarray(dx[ATT], float))
        q = quat_multiply(dq, nav[6:10])
        nav[6:10] = q / np.linalg.norm(q)
        self.bias_a -= dx[BA]
        self.bias_g -= dx[BG]

    def position_innovation(self, lat_fix, lon_fix):
        """(north, east) metres from the fix to the INS position: y = p_ins - p_fix."""
        from navgate.nav import validate

        lat_fix = validate.latitude_rad("lat_fix", lat_fix)
        lon_fix = validate.finite_scalar("lon_fix", lon_fix)
        rn, re = strapdown._frame_terms(self.nav[0], self.nav[2], self.nav[3], self.nav[4])[:2]
        return np.array([(self.nav[0] - lat_fix) * (rn + self.nav[2]),
                         (self.nav[1] - lon_fix) * (re + self.nav[2]) * math.cos(self.nav[0])])

    def update_position_2d(self, lat_fix, lon_fix, r_ne, lag_s: float = 0.0) -> UpdateResult:
        """Seed 000's TRN update: H = [I2 0], R = the fix's 2x2 covariance (m^2).

        ``lag_s`` > 0: the fix measures the INS position error ``lag_s`` seconds ago (a batch
        correlator measures the average error over its profile); then
        dp(t - lag) = dp(t) - lag dv(t) and H = [I2, -lag I2 (vN, vE), 0]. The innovation is
        formed against the INS position ``lag_s`` ago, which the caller passes as the fix
        minus that position via :meth:`update_position_offset`. With lag 0 this is
        exactly seed 000's update.
        """
        return self.update_position_offset(self.position_innovation(lat_fix, lon_fix), r_ne,
                                           lag_s)

    def update_position_offset(self, y_ne, r_ne, lag_s: float = 0.0) -> UpdateResult:
        """TRN update from y = p_ins - p_fix (north, east metres), optionally lagged.

        ``lag_s`` must be finite and >= 0 (a fix cannot measure the future)."""
        from navgate.nav import validate

        lag_s = validate.non_negative("lag_s", lag_s)
        y_ne = validate.finite_array("y_ne", y_ne, (2,))
        r_ne = validate.covariance("r_ne", r_ne, 2)
        h_matrix = np.zeros((2, N_STATES))
        h_matrix[0, 0] = h_matrix[1, 1] = 1.0
        h_matrix[0, 3] = h_matrix[1, 4] = -float(lag_s)
        return self._update(y_ne, h_matrix, r_ne, "trn")

    def update_altitude(self, h_meas, sigma) -> UpdateResult:
        """Barometric altitude update of the vertical channel: y = p_D,ins - p_D,meas
        (H = e_D; the compiled scalar update :func:`update_scalar`, the same filter as
        :meth:`update` up to float64 rounding)."""
        from navgate.nav import validate

        h_meas = validate.finite_scalar("h_meas", h_meas)
        sigma = validate.non_negative("sigma", sigma)
        dx = np.zeros(N_STATES)
        status, nis = update_scalar(self.p, self.nav, self.bias_a, self.bias_g, 2,
                                    float(h_meas) - self.nav[2], float(sigma) ** 2,
                                    self.gate1, dx)
        self.raise_for(status, "baro")
        accepted = status == UPD_ACCEPTED
        table = self.accepted if accepted else self.rejected
        table["baro"] = table.get("baro", 0) + 1
        return UpdateResult(accepted, float(nis), self.gate1, dx)

    @staticmethod
    def raise_for(status, kind):
        """The errors of :meth:`update` for a compiled update's status."""
        if status == UPD_NONFINITE:
            raise ValueError(f"{kind} update: non-finite innovation or covariance")
        if status == UPD_NOT_POSITIVE:
            raise np.linalg.LinAlgError(f"{kind} update: innovation variance not positive")


def initial_covariance(*, pos_sigma, vel_sigma, att_sigma, accel_bias_sigma, gyro_bias_sigma):
    """Diagonal P0 from 1-sigma values (scalars or 3-vectors)."""
    diag = np.concatenate([
        np.broadcast_to(pos_sigma, 3), np.broadcast_to(vel_sigma, 3),
        np.broadcast_to(att_sigma, 3), np.broadcast_to(accel_bias_sigma, 3),
        np.broadcast_to(gyro_bias_sigma, 3)]).astype(float)
    return np.diag(diag**2)
