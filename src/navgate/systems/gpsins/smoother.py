"""Fixed-interval (Rauch-Tung-Striebel) and fixed-lag smoothing of seed 002's closed-loop
GPS/INS filter, at every IMU sample, from what the forward filter stored at its GPS epochs.

Reference: Rauch, Tung and Striebel (1965), "Maximum likelihood estimates of linear dynamic
systems", AIAA J. 3(8); Gelb (ed.), *Applied Optimal Estimation* (1974), sec. 5.2-5.4
(fixed-interval and fixed-lag smoothers); Brown and Hwang, *Introduction to Random Signals
and Applied Kalman Filtering*, ch. 6 (the RTS form used here).

Between two GPS epochs e and e+1 the filter only propagates: with x_{j+1} = Phi_j (x_j + w_j)
the cross-covariance of a sample j with the prior at e+1 is P_j M_j, M_j = Phi_j' ... Phi_{s-1}',
so the RTS gain of sample j against epoch e+1 is

    A_j = P_j M_j (P^-_{e+1})^{-1},
    x^s_j = x_j + A_j (x^s_{e+1} - x^-_{e+1}),  P^s_j = P_j + A_j (P^s_{e+1} - P^-_{e+1}) A_j'.

Closed loop: the filter's estimate of the error of its (corrected) INS is zero at every
sample, and the error of the prior INS at e+1 exceeds that of the corrected one by the
correction dx_{e+1} applied there; so the innovation of the backward step is
e^s_{e+1} + dx_{e+1}, with e^s the smoothed error of the corrected INS (zero at the last
epoch of a fixed-interval pass).

The covariances between epochs are not stored by the forward pass (21 x 21 per IMU sample
would be 100 MB for the 300 s flight): an ``interval(k0, k1, P_start)`` callable
recomputes them, interval by interval, during the backward sweep. A fixed-lag smoother of
L epochs gives sample j in [t_e, t_{e+1}) the estimate from the fixes up to epoch e + L,
i.e. x(t_j | t_j + L / f_gps) exactly when the lag is a whole number of GPS periods (a
lag in between is rounded down: no more delay than asked). Its epoch-level backward steps
reuse the RTS gains A_e of the intervals already swept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from navgate.nav import validate


@njit(cache=True)
def interval_smooth(Pj, Fs, dt, Pinv, targets, dPs):
    """Backward pass over one inter-epoch interval of ``s`` steps.

    ``Pj`` (s+1, n, n) covariances of samples k0..k1 (Pj[s] the prior at the next epoch),
    ``Fs`` (s, n, n) the F of each step (Phi = I + F dt), ``Pinv`` the inverse of Pj[s];
    ``targets`` (K, n) the smoothed-minus-predicted error at the next epoch and ``dPs``
    (K, n, n) its P^s - P^- for K smoothers at once. Returns the position part of the
    smoothed error (K, s, 3) and of its covariance (K, s, 3, 3) for samples k0..k1-1, the
    full smoothed error and covariance at k0 (K, n), (K, n, n), and the RTS gain at k0."""
    s = Fs.shape[0]
    n = Pinv.shape[0]
    K = targets.shape[0]
    epos = np.empty((K, s, 3))
    pcov = np.empty((K, s, 3, 3))
    e0 = np.empty((K, n))
    P0s = np.empty((K, n, n))
    Mt = np.eye(n)
    A0 = np.empty((n, n))
    R3 = np.empty((3, n))
    A3 = np.empty((3, n))
    T3 = np.empty((3, n))
    for i in range(s - 1, -1, -1):
        # M_i = Phi_i' M_{i+1} = M + dt F_i' M
        F = Fs[i]
        new = Mt.copy()
        for r in range(n):
            for c in range(n):
                a = F[r, c]
                if a != 0.0:
                    a *= dt
                    for j in range(n):
                        new[c, j] += a * Mt[r, j]
        Mt = new
        P = Pj[i]
        if i > 0:
            for a in range(3):
                for j in range(n):
                    acc = 0.0
                    for m in range(n):
                        acc += P[a, m] * Mt[m, j]
                    R3[a, j] = acc
            for a in range(3):
                for j in range(n):
                    acc = 0.0
                    for m in range(n):
                        acc += R3[a, m] * Pinv[m, j]
                    A3[a, j] = acc
            for k in range(K):
                for a in range(3):
                    acc = 0.0
                    for m in range(n):
                        acc += A3[a, m] * targets[k, m]
                    epos[k, i, a] = acc
                dP = dPs[k]
                for a in range(3):
                    for j in range(n):
                        acc = 0.0
                        for m in range(n):
                            acc += A3[a, m] * dP[m, j]
                        T3[a, j] = acc
                for a in range(3):
                    for b in range(3):
                        acc = P[a, b]
                        for m in range(n):
                            acc += T3[a, m] * A3[b, m]
                        pcov[k, i, a, b] = acc
        else:
            A0[:, :] = (P @ Mt) @ Pinv
            for k in range(K):
                e = A0 @ targets[k]
                Ps = P + A0 @ dPs[k] @ A0.T
                Ps = 0.5 * (Ps + Ps.T)
                e0[k] = e
                P0s[k] = Ps
                for a in range(3):
                    epos[k, 0, a] = e[a]
                    for b in range(3):
                        pcov[k, 0, a, b] = Ps[a, b]
    return epos, pcov, e0, P0s, A0


def spd_inverse(P: np.ndarray) -> np.ndarray:
    """Inverse of a covariance whose states span many orders of magnitude (rad^2 of latitude
    to m^2 of height), through its correlation matrix; states with zero variance (a sensor
    error the model does not have) get zero rows and columns, and a correlation matrix that
    is singular (a direction without uncertainty) gets its pseudo-inverse (eigenvalues below
    1e-12 of the largest dropped): the pseudo-inverse throughout. ``P`` must be finite,
    symmetric and positive semi-definite (``ValueError`` naming it otherwise): a NaN or a
    negative variance would otherwise come back as a zero row, a silent "no information"."""
    P = validate.covariance("P", P)
    d = np.sqrt(np.clip(np.diag(P), 0.0, None))
    keep = d > 0
    out = np.zeros_like(P)
    if keep.any():
        dk = d[keep]
        corr = P[np.ix_(keep, keep)] / np.outer(dk, dk)
        inv = np.linalg.pinv(corr, rcond=1e-12, hermitian=True)
        out[np.ix_(keep, keep)] = inv / np.outer(dk, dk)
    return out


@dataclass
class Smoothed:
    """Position part of a smoothed solution at every sample, in the error state's units
    (d lat, d lon rad; d h m)."""

    lag_epochs: int | None  #: None: fixed-interval (RTS)
    pos_err: np.ndarray  #: (N+1, 3) estimated error of the filter's INS (subtract it)
    pos_cov: np.ndarray  #: (N+1, 3, 3) covariance of the smoothed position error


def sweep(ep_idx, p_post, p_prior, dxs, interval, n_samples: int, dt: float,
          lags=(None,)) -> list[Smoothed]:
    """Backward sweep producing one smoothed solution per entry of ``lags`` (None: RTS; an
    int L >= 0: fixed lag of L epochs, 0 giving back the filter).

    ``ep_idx`` (M+1,) the sample of each epoch (ep_idx[0] = 0, the start), ``p_post``,
    ``p_prior`` (M+1, n, n) and ``dxs`` (M+1, n) from the forward pass, ``interval(k0, k1,
    P_start) -> (Pj, Fs)`` the recomputation of the covariances between epochs,
    ``n_samples`` = N + 1.

    Checked once, before the sweep (ValueError naming the argument): ``dt`` > 0, ``ep_idx``
    whole numbers starting at 0, strictly increasing, below ``n_samples``; ``p_post``,
    ``p_prior`` finite (M+1, n, n) and ``dxs`` finite (M+1, n) (each prior covariance is
    checked symmetric positive semi-definite where it is inverted, :func:`spd_inverse`)."""
    validate.positive("dt", dt)
    n_samples = validate.positive_int("n_samples", n_samples)
    ep = validate.finite_array("ep_idx", ep_idx, (-1,))
    if ep.size == 0 or ep[0] != 0 or np.any(ep != np.round(ep)) or np.any(np.diff(ep) <= 0) \
            or ep[-1] >= n_samples:
        raise ValueError(f"ep_idx: epoch samples must be whole numbers from 0, strictly "
                         f"increasing and below n_samples = {n_samples}")
    M = len(ep_idx) - 1
    p_post = validate.finite_array("p_post", p_post)
    if p_post.ndim != 3 or p_post.shape[0] != M + 1 or p_post.shape[1] != p_post.shape[2]:
        raise ValueError(f"p_post: expected ({M + 1}, n, n), got shape {p_post.shape}")
    n = p_post.shape[1]
    validate.finite_array("p_prior", p_prior, (M + 1, n, n))
    validate.finite_array("dxs", dxs, (M + 1, n))
    K = len(lags)
    for lag in lags:
        if lag is not None and (int(lag) != lag or lag < 0):
            raise ValueError(f"lag must be a non-negative whole number of epochs, got {lag}")
    pos_err = np.zeros((K, n_samples, 3))
    pos_cov = np.empty((K, n_samples, 3, 3))
    # after the last epoch nothing is smoothed: the filter's own covariance
    last = int(ep_idx[M])
    pos_cov[:, last] = p_post[M][:3, :3]
    if last < n_samples - 1:
        Pj, _ = interval(last, n_samples - 1, p_post[M])
        pos_cov[:, last:] = Pj[:, :3, :3]
    gains: list[np.ndarray | None] = [None] * (M + 1)
    e_rts = np.zeros(n)
    P_rts = p_post[M].copy()
    targets = np.empty((K, n))
    dPs = np.empty((K, n, n))
    for e in range(M - 1, -1, -1):
        k0, k1 = int(ep_idx[e]), int(ep_idx[e + 1])
        Pj, Fs = interval(k0, k1, p_post[e])
        pinv = spd_inverse(p_prior[e + 1])
        for k, lag in enumerate(lags):
            if lag is None:
                es, Ps = e_rts, P_rts
            else:
                m = min(e + int(lag), M)
                if m <= e:
                    targets[k] = 0.0
                    dPs[k] = 0.0
                    continue
                es = np.zeros(n)
                Ps = p_post[m]
                for i in range(m - 1, e, -1):
                    A = gains[i]
                    es = A @ (es + dxs[i + 1])
                    Ps = p_post[i] + A @ (Ps - p_prior[i + 1]) @ A.T
            targets[k] = es + dxs[e + 1]
            dPs[k] = Ps - p_prior[e + 1]
        epos, pcov, e0, P0s, A0 = interval_smooth(Pj, Fs, dt, pinv, targets, dPs)
        gains[e] = A0
        pos_err[:, k0:k1] = epos
        pos_cov[:, k0:k1] = pcov
        for k, lag in enumerate(lags):
            if lag is None:
                e_rts, P_rts = e0[k], P0s[k]
    return [Smoothed(None if lag is None else int(lag), pos_err[k], pos_cov[k])
            for k, lag in enumerate(lags)]
