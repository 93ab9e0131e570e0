"""Seed 002 error model: F against finite differences of the nonlinear INS (which is how the
paper's typos were found), Phi/Q_k, the scaled GPS measurement and the closed-loop correction."""

import math

import numpy as np
import pytest

from navgate.nav.earth import radii
from navgate.nav.rotations import (
    euler_to_quat,
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
    quat_to_dcm,
    rotvec_from_quat,
    skew,
)
from navgate.systems.gpsins import filter as kf
from navgate.systems.gpsins import ins


def _vee(e):
    return np.array([e[2, 1], e[0, 2], e[1, 0]])


def _cdot(x, xd):
    """dC_b^n/dt = C [w_nb x], with w_nb = 2 vec(q* (x) q_dot)."""
    w = 2.0 * quat_multiply(quat_conjugate(x[6:10]), xd[6:10])[1:]
    return quat_to_dcm(x[6:10]) @ skew(w)


def error_rate(x, dx, f_b, w_ib, kind):
    """d/dt of the error state between the true state x and x_hat = x + dx, with the seed's
    definitions r_hat = r + dr, v_hat = v + dv, C_hat = (I - E) C (here exp(-[eps x]) C,
    the same to first order): eps_dot = vee(E_dot), E = I - C_hat C'."""
    xh = x.copy()
    xh[:6] += dx[:6]
    xh[6:10] = quat_multiply(quat_from_rotvec(-dx[6:9]), x[6:10])
    d = ins.derivatives(x, f_b, w_ib, kind)
    dh = ins.derivatives(xh, f_b, w_ib, kind)
    out = np.empty(9)
    out[:6] = dh[:6] - d[:6]
    c, ch = quat_to_dcm(x[6:10]), quat_to_dcm(xh[6:10])
    out[6:] = _vee(-(_cdot(xh, dh) @ c.T + ch @ _cdot(x, d).T))
    return out


STEPS = np.array([1e-5, 1e-5, 100.0, 1.0, 1.0, 1.0, 1e-4, 1e-4, 1e-4])


def fd_jacobian(x, f_b, w_ib, kind):
    cols = []
    for j in range(9):
        d = np.zeros(9)
        d[j] = STEPS[j]
        cols.append((error_rate(x, d, f_b, w_ib, kind) - error_rate(x, -d, f_b, w_ib, kind))
                    / (2 * STEPS[j]))
    return np.column_stack(cols)


STATES = [
    # lat (deg), h, v_ned, roll/pitch/yaw (deg), f_b, w_ib
    (40.0, 1500.0, (120.0, -80.0, 7.0), (17.0, -11.0, 57.0), (1.5, -0.7, -9.0),
     (0.05, -0.02, 0.1)),
    (-62.0, 300.0, (-40.0, 210.0, -15.0), (-30.0, 5.0, 200.0), (-0.3, 2.2, -10.5),
     (-0.1, 0.03, -0.2)),
]


def make_state(lat_deg, h, v, euler_deg):
    x = np.zeros(10)
    x[0], x[1], x[2] = math.radians(lat_deg), 0.4, h
    x[3:6] = v
    x[6:10] = euler_to_quat(*(math.radians(a) for a in euler_deg))
    return x


@pytest.mark.parametrize("case", STATES)
def test_F_matches_finite_differences_on_the_papers_sphere(case):
    """On the paper's own model (R_e constant, gamma = gamma_0 (R_e/(R_e+h))^2) the
    implemented F equals the central-difference Jacobian of the nonlinear INS. The central
    difference's truncation error is O(step^2) relative to the second derivatives; with the
    steps used (0.0006 deg, 100 m, 1 m/s, 1e-4 rad: all tiny against the scales of the
    nonlinearity, R_e and the velocities) it stays below 1e-6 of each row's largest entry."""
    lat, h, v, eul, f_b, w_ib = case
    x = make_state(lat, h, v, eul)
    F = kf.error_dynamics(x, np.array(f_b), ins.EARTH_SPHERE)
    J = fd_jacobian(x, np.array(f_b), np.array(w_ib), ins.EARTH_SPHERE)
    scale = np.abs(F).max(axis=1, keepdims=True)
    assert np.all(np.abs(F - J) <= 1e-6 * scale)


def paper_as_printed(F, x, f_b):
    """Apply the seed's printed versions of the corrected entries."""
    P = F.copy()
    lat, h, vn, ve, vd = x[0], x[2], x[3], x[4], x[5]
    R = ins.SPHERE_RADIUS + h
    t = math.tan(lat)
    printed = {}
    # typo 3: F_vr(E, h) printed +vE vD/(R+h)^2 - vN vE tan/(R+h)^2
    q = P.copy()
    q[4, 2] = ve * vd / R**2 - vn * ve * t / R**2
    printed["F_vr(E,h) sign"] = q
    # typo 4: (f^b x) instead of (f^n x)
    q = P.copy()
    fb = np.asarray(f_b)
    q[3:6, 6:9] = skew(fb)
    printed["f^b instead of f^n"] = q
    # typo 5: +((Omega + omega') x) eps
    q = P.copy()
    q[6:9, 6:9] = -P[6:9, 6:9]
    printed["+(w_in x) eps"] = q
    # typo 1: top-left block F_rv instead of F_rr
    q = P.copy()
    q[0:3, 0:3] = P[0:3, 3:6]
    printed["F_rv in place of F_rr"] = q
    return printed


def test_the_papers_printed_entries_fail_the_finite_difference_check():
    lat, h, v, eul, f_b, w_ib = STATES[0]
    x = make_state(lat, h, v, eul)
    F = kf.error_dynamics(x, np.array(f_b), ins.EARTH_SPHERE)
    J = fd_jacobian(x, np.array(f_b), np.array(w_ib), ins.EARTH_SPHERE)
    for name, bad in paper_as_printed(F, x, f_b).items():
        changed = bad != F
        assert changed.any(), name
        # the printed entries miss the finite-difference Jacobian by far more than its 1e-6
        # accuracy: the worst one by more than 10 % (of the truth, or of itself where the
        # true entry is zero)
        ref = np.maximum(np.abs(J), np.abs(bad))[changed]
        assert np.max(np.abs(bad - J)[changed] / ref) > 0.1, name


def test_skew_convention_of_E():
    """The seed prints E's bottom row as (-eps_E, -eps_N, 0); the cross-product matrix has
    (-eps_E, +eps_N, 0): E v must equal eps x v."""
    eps = np.array([0.1, -0.2, 0.3])
    v = np.array([1.0, 2.0, -0.5])
    assert np.allclose(skew(eps) @ v, np.cross(eps, v))
    assert skew(eps)[2, 1] == eps[0]


def test_propagate_is_phi_sandwich_with_the_seeds_Qk():
    """P' = Phi P Phi' + Phi G Q G' Phi' dt, Phi = I + F dt (numpy reference)."""
    rng = np.random.default_rng(3)
    lat, h, v, eul, f_b, _ = STATES[1]
    x = make_state(lat, h, v, eul)
    a = rng.normal(size=(9, 9))
    P = a @ a.T * 1e-3
    dt = 0.01
    qa = np.array([0.01, 0.02, 0.5]) ** 2
    qg = np.array([1e-3, 2e-3, 3e-3]) ** 2
    F = kf.error_dynamics(x, np.array(f_b), ins.EARTH_WGS84)
    phi = np.eye(9) + F * dt
    G = kf.noise_input(x)
    Q = np.diag(np.concatenate([qa, qg]))
    want = phi @ P @ phi.T + phi @ G @ Q @ G.T @ phi.T * dt
    got = P.copy()
    kf.propagate(got, x, np.array(f_b), dt, qa, qg, ins.EARTH_WGS84)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
    C = quat_to_dcm(x[6:10])
    np.testing.assert_allclose(G[3:6, 0:3], C)
    np.testing.assert_allclose(G[6:9, 3:6], -C)


def test_gps_update_corrects_a_known_offset():
    """Sign check of z = H x + v with errors defined INS - truth: an INS 100 m north, 50 m
    east and 20 m high of a near-perfect GPS fix is pulled back onto it, and the update's
    z reads exactly those metres (rows scaled by (R_M + h) and (R_N + h) cos lat)."""
    x_true = make_state(35.0, 800.0, (50.0, 20.0, 0.0), (0.0, 0.0, 30.0))
    rm, rn = radii(x_true[0])
    h = x_true[2]
    x = x_true.copy()
    x[0] += 100.0 / (rm + h)
    x[1] += 50.0 / ((rn + h) * math.cos(x_true[0]))
    x[2] += 20.0
    P = np.diag([(200.0 / rm) ** 2, (200.0 / rn) ** 2, 200.0**2, 1, 1, 1, 1e-4, 1e-4, 1e-4])
    gps = x_true[:3].copy()
    dx, z, S = kf.gps_update(P, x, gps, np.full(3, 0.01))
    # z uses the INS latitude and height for the scaling: equal to the offsets to 1e-4 m
    np.testing.assert_allclose(z, [100.0, 50.0, 20.0], atol=0.05)
    kf.apply_correction(x, dx)
    rm2, rn2 = radii(x[0])
    err = [(x[0] - x_true[0]) * (rm2 + h), (x[1] - x_true[1]) * (rn2 + h) * math.cos(x[0]),
           x[2] - x_true[2]]
    # a 0.01 m-sigma fix against a 200 m prior: residual below 0.01 * (1 + 1e-8) + scaling
    assert np.all(np.abs(err) < 0.06)


def test_attitude_correction_undoes_a_known_tilt():
    """C_hat = (I - E) C: an estimate eps of the error, applied with apply_correction,
    restores C (to second order in |eps|, here exactly since the injection used exp)."""
    x_true = make_state(10.0, 0.0, (0.0, 0.0, 0.0), (5.0, -3.0, 100.0))
    eps = np.array([0.01, -0.02, 0.05])
    x = x_true.copy()
    x[6:10] = quat_multiply(quat_from_rotvec(-eps), x_true[6:10])
    dx = np.zeros(9)
    dx[6:9] = eps
    kf.apply_correction(x, dx)
    d = rotvec_from_quat(quat_multiply(x[6:10], quat_conjugate(x_true[6:10])))
    assert np.max(np.abs(d)) < 1e-15 * 10
