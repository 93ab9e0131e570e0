"""Covariance analysis of seed 002's GPS/INS: the best whole-flight horizontal RMS error any
filter can reach from 1 Hz GPS position fixes and a given IMU noise, to judge the issue's
target "GPS/INS horizontal RMS at most one third of GPS-only" before flying.

Model (one horizontal channel, straight and level flight; north and east are independent
copies): position p, velocity v and tilt theta with

    p' = v,   v' = g theta + w_a,   theta' = w_g   (+ b, a constant gyro bias, optional)

w_a, w_g white with densities ``accel_noise`` (m/s^2/sqrt(Hz)) and ``gyro_noise``
(rad/s/sqrt(Hz)); p measured every second with sigma ``gps_sigma`` (seed 002: 20 m), no
fixes during the outage. The Kalman filter matched to this model is the optimal linear
estimator (Brown and Hwang 1992, ch. 5), so its covariance is a lower bound for the
paper's 9-state filter, which has exactly these states (plus the vertical channel and
heading, which do not enter the horizontal channel in level flight) but cannot know the
truth's unmodelled constant biases and must also fly the turns. The bias variant gives the
filter a bias state, which the 9-state filter does not have: a still lower bound for it.

The continuous model is discretised exactly (Van Loan 1978, "Computing integrals involving
the matrix exponential") on a 0.1 s grid; the expected horizontal mean square over the
flight is twice the mean of the position variance over the grid (the errors are zero-mean).
The GPS-only mean square is 2 gps_sigma^2, so the expected ratio is
sqrt(mean var_p) / gps_sigma.

:func:`trajectory_bound` is the trajectory-exact version: a linear covariance
analysis along the scenario's actual trajectory (climb, turns, speed change: F evaluated on
the truth and the error-free readings at every IMU sample) carrying every error state the
sensor model has (position, velocity, attitude and, where the model has them, the
accelerometer and gyro biases and scale factors; :mod:`navgate.systems.gpsins.augmented`),
with the sensor model's white noise and the scenario's GPS epochs and outage. The matched
filter's covariance is the causal bound, its RTS and fixed-lag smoothers' covariances
(:mod:`navgate.systems.gpsins.smoother`) the bounds of those smoothers. The expected
whole-flight ratio is sqrt(mean over the IMU samples of (P_NN + P_EE)) / (sqrt(2)
gps_sigma), the quantity the scenario's pooled ratio estimates; the outage-excluded ratio
takes the mean over the samples outside the outage. The one-channel bound above stays as
a cross-check (it lacks the Schuler loop, the Earth rate, the turns and the biases' full
geometry, so it agrees only to within a few per cent: tests/systems/gpsins/test_bound.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from navgate.systems.gpsins import augmented, smoother

G = 9.80665


@dataclass(frozen=True)
class BoundResult:
    rms_horizontal_m: float  #: expected whole-flight horizontal RMS of the optimal filter
    ratio_to_gps_only: float  #: that over the GPS-only RMS, sqrt(2) gps_sigma
    max_sigma_horizontal_outage_m: float  #: largest horizontal 1-sigma in the outage
    position_var: np.ndarray  #: (n,) position variance per axis on the grid (m^2)
    t: np.ndarray  #: (n,) grid times (s)


def discretise(F: np.ndarray, Qc: np.ndarray, h: float):
    """(Phi, Qd) for x' = F x + w, E[w w'] = Qc delta: Van Loan's block exponential."""
    n = F.shape[0]
    m = np.zeros((2 * n, 2 * n))
    m[:n, :n] = -F
    m[:n, n:] = Qc
    m[n:, n:] = F.T
    e = expm(m * h)
    phi = e[n:, n:].T
    return phi, phi @ e[:n, n:]


def channel_model(gyro_noise: float, accel_noise: float, gyro_bias: float = 0.0):
    """F, Qc and the state count of the horizontal channel (p, v, theta[, b])."""
    n = 4 if gyro_bias > 0 else 3
    F = np.zeros((n, n))
    F[0, 1] = 1.0
    F[1, 2] = G
    if n == 4:
        F[2, 3] = 1.0
    Qc = np.zeros((n, n))
    Qc[1, 1] = accel_noise ** 2
    Qc[2, 2] = gyro_noise ** 2
    return F, Qc


def flight_bound(gyro_noise: float, accel_noise: float = 1e-3, *, gyro_bias: float = 0.0,
                 gps_sigma: float = 20.0, duration_s: float = 300.0,
                 outage_start_s: float = 240.0, outage_s: float = 30.0,
                 p0: tuple[float, float, float] = (5.0, 0.1, 0.1 * math.pi / 180.0),
                 h: float = 0.1) -> BoundResult:
    """Optimal-filter covariance over a flight with 1 Hz fixes and one outage.

    ``gyro_noise`` rad/s/sqrt(Hz), ``accel_noise`` m/s^2/sqrt(Hz), ``gyro_bias`` rad/s
    (1 sigma of a constant bias, given to the filter as a state), ``p0`` the initial
    1-sigma of (p, v, theta) (the scenario's alignment)."""
    if not (gyro_noise >= 0 and accel_noise >= 0 and gyro_bias >= 0 and gps_sigma > 0):
        raise ValueError("noise densities must be non-negative and gps_sigma positive")
    F, Qc = channel_model(gyro_noise, accel_noise, gyro_bias)
    n = F.shape[0]
    phi, qd = discretise(F, Qc, h)
    P = np.diag([p0[0] ** 2, p0[1] ** 2, p0[2] ** 2] + ([gyro_bias ** 2] if n == 4 else []))
    steps = int(round(duration_s / h))
    per_fix = int(round(1.0 / h))
    r = gps_sigma ** 2
    var = np.empty(steps)
    t = np.arange(1, steps + 1) * h
    for k in range(steps):
        P = phi @ P @ phi.T + qd
        tk = t[k]
        if (k + 1) % per_fix == 0 and not (outage_start_s <= tk < outage_start_s + outage_s):
            gain = P[:, 0] / (P[0, 0] + r)
            P = P - np.outer(gain, P[0, :])
            P = 0.5 * (P + P.T)
        var[k] = P[0, 0]
    out = (t >= outage_start_s) & (t < outage_start_s + outage_s)
    rms = math.sqrt(2.0 * var.mean())
    return BoundResult(rms, rms / (math.sqrt(2.0) * gps_sigma),
                       math.sqrt(2.0 * var[out].max()) if out.any() else 0.0, var, t)


@dataclass
class TrajectoryBound:
    """Expected horizontal error of the matched filter and its smoothers along one
    trajectory (every IMU sample)."""

    gps_sigma: float
    outage: np.ndarray  #: (N+1,) True inside the GPS outage
    var_h_causal: np.ndarray  #: (N+1,) P_NN + P_EE of the filter (m^2)
    var_h_smoothed: dict  #: lag in epochs (None: RTS) -> (N+1,) P_NN + P_EE (m^2)
    n_states: int
    state_names: list

    def _ratio(self, var, outage_excluded=False):
        v = var[~self.outage] if outage_excluded else var
        return math.sqrt(v.mean()) / (math.sqrt(2.0) * self.gps_sigma)

    @property
    def ratio_causal(self) -> float:
        """Expected whole-flight ratio (outage included) of the matched filter."""
        return self._ratio(self.var_h_causal)

    @property
    def ratio_causal_outage_excluded(self) -> float:
        return self._ratio(self.var_h_causal, True)

    def ratio_smoothed(self, lag=None, outage_excluded=False) -> float:
        """Expected ratio of the RTS (``lag`` None) or fixed-lag smoother."""
        return self._ratio(self.var_h_smoothed[lag], outage_excluded)


def trajectory_bound(states, f, w, dt, ep_idx, valid, P0, qa, qg, gps_sigma, off, outage,
                     lags=(None,)) -> TrajectoryBound:
    """Covariance analysis along a trajectory: ``states`` (N+1, 10) the truth, ``f``, ``w``
    (N, 3) its error-free readings, ``qa``, ``qg`` (N, 3) the white-noise densities per step,
    ``ep_idx`` (M+1,) the GPS epochs (ep_idx[0] = 0), ``valid`` (M,) False in the outage,
    ``P0`` (n, n) the initial covariance in the layout ``off``
    (:func:`navgate.systems.gpsins.augmented.layout`), ``outage`` (N+1,) the outage
    samples; ``lags``: smoothers to bound (None: RTS, L: fixed lag of L epochs)."""
    if not gps_sigma > 0:
        raise ValueError("gps_sigma must be positive")
    states = np.ascontiguousarray(states, dtype=float)
    f, w = np.ascontiguousarray(f, dtype=float), np.ascontiguousarray(w, dtype=float)
    qa, qg = np.ascontiguousarray(qa, dtype=float), np.ascontiguousarray(qg, dtype=float)
    ep_idx = np.asarray(ep_idx, dtype=np.int64)
    sigma = np.full(3, float(gps_sigma))
    P0 = np.ascontiguousarray(P0, dtype=float)
    ppos, p_post, p_prior = augmented.covariance_run(states, f, w, qa, qg, dt, ep_idx,
                                                     np.asarray(valid, bool), P0, sigma, off)
    scale = augmented.position_scale(states)

    def interval(k0, k1, P_start):
        return augmented.interval_covariances(np.ascontiguousarray(P_start), states, f, w, qa,
                                              qg, dt, k0, k1, off)

    smoothed = {}
    if lags:
        zero = np.zeros((len(ep_idx), P0.shape[0]))
        for sm in smoother.sweep(ep_idx, p_post, p_prior, zero, interval, len(states), dt,
                                 lags):
            c = sm.pos_cov
            smoothed[sm.lag_epochs] = (c[:, 0, 0] * scale[:, 0] ** 2
                                       + c[:, 1, 1] * scale[:, 1] ** 2)
    return TrajectoryBound(float(gps_sigma), np.asarray(outage, bool),
                           ppos[:, 0, 0] + ppos[:, 1, 1], smoothed, P0.shape[0],
                           augmented.state_names(off))
