"""15-state error-state filter: F against the nonlinear mechanization, sparse propagation
against the dense product, sign convention with an injected offset, gating, bad input."""

import math

import numpy as np
import pytest
from numba import njit

from navgate.nav import eskf, strapdown
from navgate.nav.earth import radii
from navgate.nav.rotations import quat_from_rotvec, quat_multiply, quat_to_dcm
from navgate.sim import trajectory as tr

LAT0 = math.radians(36.6)
QUIET = eskf.FilterConfig(1e-12, 1e-12, 1e-12, 1e9, 1e-12, 1e9)


@pytest.fixture(scope="module")
def turning_flight():
    traj = tr.generate([tr.straight(5), tr.turn(90, 3)], lat0=LAT0, lon0=math.radians(-84.2),
                       h0=1300, heading0=0.3, speed0=60, rate_hz=400.0, duration_s=20)
    return traj, *traj.imu()


def _error(f, ref):
    rn, re = radii(ref.nav[0])
    dp = [(f.nav[0] - ref.nav[0]) * (rn + ref.nav[2]),
          (f.nav[1] - ref.nav[1]) * (re + ref.nav[2]) * math.cos(ref.nav[0]),
          -(f.nav[2] - ref.nav[2])]
    e = quat_to_dcm(f.nav[6:10]) @ quat_to_dcm(ref.nav[6:10]).T
    psi = 0.5 * np.array([e[2, 1] - e[1, 2], e[0, 2] - e[2, 0], e[1, 0] - e[0, 1]])
    return np.concatenate([dp, f.nav[3:6] - ref.nav[3:6], psi])


def test_error_dynamics_match_perturbed_mechanization(turning_flight):
    """Phi (chained over 1 s of a turn) predicts what a perturbed INS actually does."""
    traj, gyro, accel = turning_flight
    k0, n = 4000, 400
    x0 = traj.states[k0].copy()

    def run(nav, ba=None, bg=None):
        f = eskf.ErrorStateFilter(nav, np.eye(15), QUIET, bias_a0=ba, bias_g0=bg)
        f.propagate(gyro, accel, k0, k0 + n, propagate_p=False)
        return f

    ref = run(x0)
    nav = x0.copy()
    phi_total = np.eye(15)
    c_old, c_new, f_n, phi = np.empty((3, 3)), np.empty((3, 3)), np.empty(3), np.zeros((15, 15))
    for k in range(k0, k0 + n):
        lat, h, vn, ve = nav[0], nav[2], nav[3], nav[4]
        strapdown.mechanize_step(nav, gyro[k], accel[k], traj.dt, c_old, c_new, f_n)
        phi[:] = 0.0
        eskf._build_phi(phi, c_old, f_n, lat, h, vn, ve, traj.dt, 1.0, 1.0)
        phi_total = phi @ phi_total
    cases = {6: 1e-3, 7: 1e-3, 8: 1e-3, 9: 1e-2, 10: 1e-2, 11: 1e-2, 12: 1e-4, 14: 1e-4, 3: 0.1}
    for idx, val in cases.items():
        dx = np.zeros(15)
        dx[idx] = val
        nav = x0.copy()
        ba, bg = np.zeros(3), np.zeros(3)
        if 3 <= idx < 6:
            nav[idx] += val
        elif 6 <= idx < 9:
            nav[6:10] = quat_multiply(quat_from_rotvec(dx[6:9]), nav[6:10])
        elif 9 <= idx < 12:
            ba = dx[9:12]
        else:
            bg = dx[12:15]
        nonlinear = _error(run(nav, ba, bg), ref)
        linear = (phi_total @ dx)[:9]
        # residuals: second order in the perturbation (<= 1e-3 relative) plus the O(|F| dt)
        # difference between I + F dt and the exact step Jacobian (|F| dt <= 0.03 here)
        scale = np.abs(linear).max()
        assert np.abs(nonlinear - linear).max() <= 0.05 * scale, (idx, nonlinear, linear)


def test_sparse_propagation_equals_dense_product():
    rng = np.random.default_rng(3)
    a = rng.standard_normal((15, 15))
    p = a @ a.T
    phi = np.zeros((15, 15))
    c = quat_to_dcm(np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm([0.9, 0.1, -0.3, 0.2]))
    eskf._build_phi(phi, c, np.array([1.0, -2.0, -9.7]), LAT0, 500.0, 50.0, -20.0, 0.0025,
                    0.999, 0.998)
    # the pattern covers every non-zero of Phi
    mask = np.zeros((15, 15), bool)
    for i in range(15):
        mask[i, eskf.PHI_COLS[i, : eskf.PHI_NNZ[i]]] = True
    assert not np.any(phi[~mask])
    q = rng.uniform(0, 1e-3, 15)
    expected = phi @ p @ phi.T + np.diag(q)
    work = np.empty((15, 15))
    eskf.propagate_covariance(p, phi, work, q)
    assert np.allclose(p, expected, rtol=1e-12, atol=1e-12)
    assert np.array_equal(p, p.T)


def _filter(p0_pos=100.0):
    nav = strapdown.make_nav_state(LAT0, 0.5, 1000.0, [50.0, 0.0, 0.0], [1, 0, 0, 0])
    p0 = eskf.initial_covariance(pos_sigma=p0_pos, vel_sigma=1.0, att_sigma=1e-3,
                                 accel_bias_sigma=1e-2, gyro_bias_sigma=1e-4)
    return eskf.ErrorStateFilter(nav, p0, QUIET)


def test_injected_position_offset_is_removed_with_the_right_sign():
    f = _filter()
    rn, re = radii(LAT0)
    lat_true, lon_true = f.nav[0], f.nav[1]
    f.nav[0] += 100.0 / (rn + 1000.0)  # INS 100 m north of the truth
    f.nav[1] -= 40.0 / ((re + 1000.0) * math.cos(LAT0))  # and 40 m west
    res = f.update_position_2d(lat_true, lon_true, np.eye(2) * 1.0)
    assert res.accepted
    # dx = estimated - true: +100 north, -40 east, scaled by K = P/(P+R) = 1e4/(1e4+1).
    # The innovation is formed with the radii at the INS latitude, 100 m from where the
    # offset was computed: relative change 3 e^2 sin(lat)cos(lat) dlat ~ 1.5e-7 north, and
    # tan(lat) dlat ~ 1.2e-5 east (cos(lat) of the shifted latitude).
    assert math.isclose(res.correction[0], 100.0 * 1e4 / (1e4 + 1), rel_tol=5e-7)
    assert math.isclose(res.correction[1], -40.0 * 1e4 / (1e4 + 1), rel_tol=2e-5)
    err_n = (f.nav[0] - lat_true) * (rn + 1000.0)
    err_e = (f.nav[1] - lon_true) * (re + 1000.0) * math.cos(LAT0)
    assert math.hypot(err_n, err_e) < 0.02
    # Joseph form: posterior position variance = P R / (P + R)
    assert math.isclose(f.p[0, 0], 1e4 * 1.0 / (1e4 + 1.0), rel_tol=1e-9)
    assert np.array_equal(f.p, f.p.T)


def test_lagged_fix_corrects_velocity_too():
    f = _filter(p0_pos=1.0)
    f.p[3, 3] = f.p[4, 4] = 4.0
    f.nav[3] += 1.0  # north velocity error +1 m/s: 10 s ago the INS was 10 m further south
    y = np.array([-10.0, 0.0])  # INS - fix, measured 10 s ago, position error now zero
    res = f.update_position_offset(y, np.eye(2) * 0.01, lag_s=10.0)
    assert res.accepted
    # y = dp - 10 dv with dp ~ 0 (sigma 1 m): the filter attributes it to velocity:
    # K_v = 10 P_v / (P_p + 100 P_v + R) -> dv = 10 * 4 * 10 / (1 + 400 + 0.01) ~ 0.9975
    assert math.isclose(res.correction[3], 400.0 / 401.01, rel_tol=1e-6)


def test_baro_update_sign():
    f = _filter()
    f.p[2, 2] = 100.0
    f.nav[2] += 20.0  # INS 20 m too high
    res = f.update_altitude(1000.0, 0.1)
    assert res.accepted and math.isclose(f.nav[2], 1000.0, abs_tol=0.01)


def test_gate_rejects_outlier_and_counts_it():
    f = _filter(p0_pos=5.0)
    nav_before = f.nav.copy()
    p_before = f.p.copy()
    rn, _ = radii(LAT0)
    res = f.update_position_2d(f.nav[0] + 500.0 / rn, f.nav[1], np.eye(2) * 4.0)
    assert not res.accepted and res.nis > res.gate
    assert f.rejected["trn"] == 1 and f.accepted.get("trn", 0) == 0
    assert np.array_equal(f.nav, nav_before) and np.array_equal(f.p, p_before)
    assert math.isclose(res.gate, 13.815510557964274)  # chi2(2).ppf(0.999)


def test_singular_and_non_finite_inputs_raise():
    f = _filter()
    f.p[:2, :] = 0.0
    f.p[:, :2] = 0.0
    with pytest.raises(np.linalg.LinAlgError):
        f.update_position_offset([1.0, 1.0], np.zeros((2, 2)))
    with pytest.raises(ValueError):
        _filter().update_position_offset([np.nan, 0.0], np.eye(2))
    with pytest.raises(ValueError):
        eskf.ErrorStateFilter(np.zeros(5), np.eye(15), QUIET)


def test_non_finite_imu_samples_are_held_and_counted(turning_flight):
    traj, gyro, accel = turning_flight
    bad_gyro, bad_accel = gyro.copy(), accel.copy()
    bad_gyro[1000, 2] = np.nan
    bad_accel[2000, 0] = np.inf
    bad_accel[2001] = np.nan
    p0 = eskf.initial_covariance(pos_sigma=5, vel_sigma=0.1, att_sigma=1e-3,
                                 accel_bias_sigma=1e-2, gyro_bias_sigma=1e-4)
    clean = eskf.ErrorStateFilter(traj.states[0], p0, QUIET)
    clean.propagate(gyro, accel, 0, len(gyro))
    f = eskf.ErrorStateFilter(traj.states[0], p0, QUIET)
    f.propagate(bad_gyro, bad_accel, 0, len(gyro))
    assert f.imu_samples_rejected == 3
    assert np.all(np.isfinite(f.nav)) and np.all(np.isfinite(f.p))
    # holding the previous reading for 3 of 8000 samples of smooth motion costs micrometres
    rn, _ = radii(LAT0)
    assert abs(f.nav[0] - clean.nav[0]) * rn < 1e-3


@njit(cache=False)
def _plain_propagation(nav, p, gyro, accel, dt, q_diag, decay_a, decay_g):
    """The textbook step, P <- Phi P Phi' + Q with dense triple loops, over the same
    mechanization (an independent statement of what the filter's loop computes)."""
    c_old, c_new, f_n = np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    phi = np.zeros((15, 15))
    tmp = np.empty((15, 15))
    for k in range(gyro.shape[0]):
        lat, h, vn, ve = nav[0], nav[2], nav[3], nav[4]
        strapdown.mechanize_step(nav, gyro[k], accel[k], dt, c_old, c_new, f_n)
        eskf._build_phi(phi, c_old, f_n, lat, h, vn, ve, dt, decay_a, decay_g)
        for i in range(15):
            for j in range(15):
                acc = 0.0
                for m in range(15):
                    acc += phi[i, m] * p[m, j]
                tmp[i, j] = acc
        for i in range(15):
            for j in range(15):
                acc = 0.0
                for m in range(15):
                    acc += tmp[i, m] * phi[j, m]
                p[i, j] = acc + (q_diag[i] if i == j else 0.0)


def test_covariance_over_a_ten_minute_flight_equals_the_dense_product(seconds=600.0):
    """The vectorised sparse covariance step (padded rows, Phi's non-zeros only, upper
    triangle mirrored) against dense Phi P Phi' + Q over 240,000 samples of manoeuvring
    flight: every element within 1e-12 of sqrt(P_ii P_jj). Summation order differs
    (the dense sum adds exact zeros, the sparse one skips them), so the two agree to
    rounding accumulated over the flight, not bit for bit; a wrong coefficient, a missed
    non-zero or a transposed product is off by many orders more."""
    segs = [tr.straight(40), tr.turn(90, 3), tr.climb(150, 5), tr.speed_change(75, 40),
            tr.turn(-135, 4), tr.straight(30)]
    traj = tr.generate(segs, lat0=LAT0, lon0=math.radians(-84.2), h0=1200.0, heading0=0.4,
                       speed0=60.0, rate_hz=400.0, duration_s=seconds)
    gyro, accel = traj.imu()
    cfg = eskf.FilterConfig(1e-3, 1e-4, 1e-3, 3600.0, 1e-5, 3600.0)
    p0 = eskf.initial_covariance(pos_sigma=5, vel_sigma=0.1, att_sigma=1e-3,
                                 accel_bias_sigma=1e-2, gyro_bias_sigma=1e-4)
    f = eskf.ErrorStateFilter(traj.states[0], p0, cfg)
    f.propagate(gyro, accel, 0, len(gyro))
    nav, p = traj.states[0].copy(), p0.copy()
    _plain_propagation(nav, p, gyro, accel, traj.dt, f.q_diag, f.decay_a, f.decay_g)
    # the same mechanization, compiled in another loop: equal up to rounding
    np.testing.assert_allclose(f.nav, nav, rtol=1e-12, atol=1e-12)
    assert np.array_equal(f.p, f.p.T)
    scale = np.sqrt(np.outer(np.diag(p), np.diag(p)))
    rel = np.max(np.abs(f.p - p) / scale)
    assert rel < 1e-12, rel
    assert np.max(np.abs(p - p0) / scale) > 1e-3  # P did move over the flight


def test_compiled_altitude_update_equals_the_generic_joseph_update():
    """update_altitude (compiled, H = e_D written out) against update() with the matrices,
    accepted and rejected, on a correlated P."""
    rng = np.random.default_rng(3)
    a = rng.standard_normal((15, 15))
    for h_meas, accepted in ((1003.0, True), (1400.0, False)):
        f, g = _filter(), _filter()
        p = a @ a.T + 10 * np.eye(15)
        f.p, g.p = p.copy(), p.copy()
        h_matrix = np.zeros((1, 15))
        h_matrix[0, 2] = 1.0
        want = g.update([h_meas - g.nav[2]], h_matrix, [[0.5**2]], "baro")
        got = f.update_altitude(h_meas, 0.5)
        assert got.accepted == want.accepted == accepted
        assert math.isclose(got.nis, want.nis, rel_tol=1e-14) and got.gate == want.gate
        assert f.accepted == g.accepted and f.rejected == g.rejected
        np.testing.assert_allclose(got.correction, want.correction, rtol=1e-12, atol=1e-15)
        scale = np.sqrt(np.outer(np.diag(g.p), np.diag(g.p)))
        assert np.max(np.abs(f.p - g.p) / scale) < 1e-13
        assert np.array_equal(f.p, f.p.T)
        np.testing.assert_allclose(f.nav, g.nav, rtol=1e-15, atol=1e-15)
        np.testing.assert_allclose(f.bias_a, g.bias_a, rtol=1e-13, atol=1e-18)


def test_compiled_altitude_update_raises_like_the_generic_one():
    f = _filter()
    with pytest.raises(ValueError, match="h_meas"):
        f.update_altitude(np.nan, 1.0)
    f.p[2, 2] = -1.0
    with pytest.raises(np.linalg.LinAlgError, match="not positive"):
        f.update_altitude(1000.0, 0.1)


def test_chi2_gate_is_scipy_chi2_ppf():
    from scipy.stats import chi2

    for prob, dof in ((0.999, 1), (0.999, 2), (0.99, 7), (0.9999, 40)):
        assert eskf.chi2_gate(prob, dof) == chi2.ppf(prob, dof)
