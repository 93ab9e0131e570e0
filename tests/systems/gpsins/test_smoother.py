"""Seed 002 smoothers (navgate.systems.gpsins.smoother) on a small linear model against the
batch (information-form) solution, which is exact: the posterior of all samples given the
fixes up to an epoch is the Gaussian conditional of the joint prior (Gelb 1974, sec. 5.1).
RTS must equal it with every fix, a fixed lag of L epochs with the fixes up to e + L, lag 0
the filter; estimates and covariances alike, at fixes and between them."""

import numpy as np
import pytest

from navgate.systems.gpsins import smoother

N_STATE = 5
STEPS = 4  # samples per epoch
EPOCHS = 9
DT = 0.25


def model():
    """(p1, p2, p3, v, b): p1' = v, v' = b + w, p2 couples to p1, p3 a random walk."""
    F = np.zeros((N_STATE, N_STATE))
    F[0, 3] = 1.0
    F[3, 4] = 1.0
    F[1, 0] = 0.3
    F[1, 1] = -0.2
    Qc = np.diag([0.0, 0.05, 0.2, 0.4, 0.0])
    P0 = np.diag([4.0, 2.0, 3.0, 1.0, 0.25])
    R = np.diag([1.5, 0.7, 2.0])
    return F, Qc, P0, R


def forward(F, Qc, P0, R, z, valid):
    """Closed-loop-style filter: the nominal is the estimate, dx = prior - posterior."""
    phi = np.eye(N_STATE) + F * DT
    H = np.zeros((3, N_STATE))
    H[:, :3] = np.eye(3)
    n_samp = STEPS * EPOCHS + 1
    x = np.zeros(N_STATE)
    P = P0.copy()
    xs = np.empty((n_samp, N_STATE))
    xs[0] = x
    p_post = [P0.copy()]
    p_prior = [P0.copy()]
    dxs = [np.zeros(N_STATE)]
    for k in range(n_samp - 1):
        P = phi @ (P + Qc * DT) @ phi.T
        x = phi @ x
        if (k + 1) % STEPS == 0:
            e = (k + 1) // STEPS
            p_prior.append(P.copy())
            dx = np.zeros(N_STATE)
            if valid[e - 1]:
                S = H @ P @ H.T + R
                K = P @ H.T @ np.linalg.inv(S)
                xn = x + K @ (z[e - 1] - H @ x)
                dx = x - xn
                x = xn
                P = (np.eye(N_STATE) - K @ H) @ P
            p_post.append(P.copy())
            dxs.append(dx)
        xs[k + 1] = x
    return xs, np.array(p_post), np.array(p_prior), np.array(dxs)


def interval_fn(F, Qc):
    def interval(k0, k1, P_start):
        s = k1 - k0
        Pj = np.empty((s + 1, N_STATE, N_STATE))
        Pj[0] = P_start
        phi = np.eye(N_STATE) + F * DT
        for i in range(s):
            Pj[i + 1] = phi @ (Pj[i] + Qc * DT) @ phi.T
        return Pj, np.repeat(F[None], s, axis=0)
    return interval


def joint_prior(F, Qc, P0):
    """Covariance of all samples stacked (x_{j+1} = Phi (x_j + w_j))."""
    phi = np.eye(N_STATE) + F * DT
    n_samp = STEPS * EPOCHS + 1
    n_src = N_STATE * n_samp  # x0 and w_0..w_{N-1}
    T = np.zeros((N_STATE * n_samp, n_src))
    T[:N_STATE, :N_STATE] = np.eye(N_STATE)
    for k in range(n_samp - 1):
        rows = slice(N_STATE * (k + 1), N_STATE * (k + 2))
        T[rows] = phi @ T[N_STATE * k:N_STATE * (k + 1)]
        T[rows, N_STATE * (k + 1):N_STATE * (k + 2)] += phi
    src = np.zeros((n_src, n_src))
    src[:N_STATE, :N_STATE] = P0
    for k in range(n_samp - 1):
        sl = slice(N_STATE * (k + 1), N_STATE * (k + 2))
        src[sl, sl] = Qc * DT
    return T @ src @ T.T


def batch(sigma, R, z, valid, upto):
    """Posterior mean and covariance of every sample given the valid fixes of epochs
    1..upto."""
    rows, zs, rs = [], [], []
    for e in range(1, upto + 1):
        if valid[e - 1]:
            for a in range(3):
                rows.append(N_STATE * (e * STEPS) + a)
                zs.append(z[e - 1, a])
                rs.append(R[a, a])
    if not rows:
        return np.zeros(sigma.shape[0]), sigma
    Hs = np.zeros((len(rows), sigma.shape[0]))
    Hs[np.arange(len(rows)), rows] = 1.0
    S = Hs @ sigma @ Hs.T + np.diag(rs)
    G = sigma @ Hs.T @ np.linalg.inv(S)
    return G @ np.array(zs), sigma - G @ Hs @ sigma


@pytest.fixture(scope="module")
def case():
    F, Qc, P0, R = model()
    rng = np.random.default_rng(5)
    z = rng.normal(size=(EPOCHS, 3)) * 2.0
    valid = np.ones(EPOCHS, bool)
    valid[4:6] = False  # an outage
    xs, p_post, p_prior, dxs = forward(F, Qc, P0, R, z, valid)
    ep_idx = np.arange(EPOCHS + 1) * STEPS
    sig = joint_prior(F, Qc, P0)
    out = smoother.sweep(ep_idx, p_post, p_prior, dxs, interval_fn(F, Qc), len(xs), DT,
                         lags=(None, 0, 1, 3))
    return dict(F=F, Qc=Qc, R=R, z=z, valid=valid, xs=xs, sig=sig, out=out)


def _compare(case, sm, upto_of_sample):
    xs, sig = case["xs"], case["sig"]
    for j in range(len(xs)):
        mean, cov = batch(sig, case["R"], case["z"], case["valid"], upto_of_sample(j))
        sl = slice(N_STATE * j, N_STATE * j + 3)
        np.testing.assert_allclose(xs[j, :3] - sm.pos_err[j], mean[sl], atol=1e-10)
        np.testing.assert_allclose(sm.pos_cov[j], cov[sl, sl], atol=1e-10)


def test_rts_equals_the_batch_posterior_given_every_fix(case):
    _compare(case, case["out"][0], lambda j: EPOCHS)


@pytest.mark.parametrize("which, lag", [(1, 0), (2, 1), (3, 3)])
def test_fixed_lag_equals_the_batch_posterior_given_the_fixes_up_to_the_lag(case, which, lag):
    """Sample j in [t_e, t_e+1) gets the fixes of epochs up to e + lag (lag 0: the filter)."""
    _compare(case, case["out"][which], lambda j: min(j // STEPS + lag, EPOCHS))


def test_spd_inverse_handles_scales_and_zero_states():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(4, 4))
    P = a @ a.T + np.eye(4)
    D = np.diag([1e-7, 1.0, 30.0, 1e-3])
    Ps = D @ P @ D
    want = np.linalg.inv(P)  # inv(D P D) = D^-1 inv(P) D^-1
    np.testing.assert_allclose(D @ smoother.spd_inverse(Ps) @ D, want, rtol=1e-10)
    Z = np.zeros((5, 5))
    Z[:4, :4] = Ps
    inv = smoother.spd_inverse(Z)
    assert np.all(inv[4] == 0) and np.all(inv[:, 4] == 0)
    np.testing.assert_allclose(D @ inv[:4, :4] @ D, want, rtol=1e-10)


@pytest.mark.parametrize("bad, what", [
    (np.full((3, 3), np.nan), "non-finite"),
    (-np.eye(3), "positive semi-definite"),
    (np.array([[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), "symmetric"),
    (np.ones((3, 2)), "shape"),
])
def test_spd_inverse_rejects_what_is_not_a_covariance(bad, what):
    # before: NaN and -I both came back as all zeros (a silent "no information")
    with pytest.raises(ValueError, match=f"^P: .*{what}"):
        smoother.spd_inverse(bad)


def test_bad_lag_is_rejected():
    F, Qc, P0, R = model()
    with pytest.raises(ValueError):
        smoother.sweep(np.array([0, STEPS]), np.array([P0, P0]), np.array([P0, P0]),
                       np.zeros((2, N_STATE)), interval_fn(F, Qc), STEPS + 1, DT, lags=(1.5,))
