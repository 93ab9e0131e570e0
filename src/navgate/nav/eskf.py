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


@njit(cache=True)
def propagate_covariance(p, phi, work, q_diag):
    """P <- Phi P Phi' + diag(q_diag), using Phi's sparsity; P stays exactly symmetric."""
    n = 15
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for m in range(PHI_NNZ[i]):
                k = PHI_COLS[i, m]
                acc += phi[i, k] * p[k, j]
            work[i, j] = acc
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for m in range(PHI_NNZ[j]):
                k = PHI_COLS[j, m]
                acc += work[i, k] * phi[j, k]
            if i == j:
                acc += q_diag[i]
            p[i, j] = acc
            p[j, i] = acc


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
    work = np.empty((15, 15))
    w = np.empty(3)
    f = np.empty(3)
    bad = 0
    for k in range(k0, k1):
        finite = True
        for i in range(3):
            if not (math.isfinite(gyro[k, i]) and math.isfinite(accel[k, i])):
                finite = False
        if finite:
            for i in range(3):
                last_good[i] = gyro[k, i]
                last_good[3 + i] = accel[k, i]
        else:
            bad += 1
        for i in range(3):
            w[i] = last_good[i] - bias_g[i]
            f[i] = last_good[3 + i] - bias_a[i]
        lat, h, vn, ve = nav[0], nav[2], nav[3], nav[4]
        strapdown.mechanize_step(nav, w, f, dt, c_old, c_new, f_n)
        if propagate_p:
            _build_phi(phi, c_old, f_n, lat, h, vn, ve, dt, decay_a, decay_g)
            propagate_covariance(p, phi, work, q_diag)
        if (k + 1) % out_every == 0:
            row = (k + 1 - out_offset) // out_every
            if 0 <= row < out_nav.shape[0]:
                out_nav[row] = nav
                for i in range(15):
                    out_sigma[row, i] = math.sqrt(max(p[i, i], 0.0))
    return bad


def _readings(name, value):
    """An (N, 3) array (the compiled loop indexes [k, 0..2]); an ndarray is passed on as it
    is (no copy: callers hand the whole flight's readings with a k0..k1 window each call)."""
    a = value if isinstance(value, np.ndarray) else np.asarray(value, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name}: expected an N x 3 array, got shape {a.shape}")
    return a


@functools.lru_cache(maxsize=64)
def chi2_gate(probability: float, dof: int) -> float:
    """Chi-square gate: the ``probability`` quantile with ``dof`` degrees of freedom.

    Cached per (probability, dof): the value depends on the configuration only, and
    ``scipy.stats.chi2.ppf`` was 57 % of each barometer update's cost (issue 32).
    """
    from scipy.stats import chi2

    return float(chi2.ppf(probability, dof))


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
        """Barometric altitude update of the vertical channel: y = p_D,ins - p_D,meas."""
        from navgate.nav import validate

        h_meas = validate.finite_scalar("h_meas", h_meas)
        sigma = validate.non_negative("sigma", sigma)
        h_matrix = np.zeros((1, N_STATES))
        h_matrix[0, 2] = 1.0
        return self._update(np.array([h_meas - self.nav[2]]), h_matrix, np.array([[sigma**2]]),
                            "baro")


def initial_covariance(*, pos_sigma, vel_sigma, att_sigma, accel_bias_sigma, gyro_bias_sigma):
    """Diagonal P0 from 1-sigma values (scalars or 3-vectors)."""
    diag = np.concatenate([
        np.broadcast_to(pos_sigma, 3), np.broadcast_to(vel_sigma, 3),
        np.broadcast_to(att_sigma, 3), np.broadcast_to(accel_bias_sigma, 3),
        np.broadcast_to(gyro_bias_sigma, 3)]).astype(float)
    return np.diag(diag**2)
