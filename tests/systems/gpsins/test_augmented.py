"""Seed 002 full filter (navgate.systems.gpsins.augmented): its propagation and update against
dense textbook forms, the sensor columns of F against the nonlinear INS, the sign conventions
through the estimated biases, and the covariance between epochs the smoother recomputes."""

import math
from dataclasses import replace

import numpy as np
import pytest

from navgate.nav.rotations import euler_to_quat, quat_conjugate, quat_multiply, quat_to_dcm
from navgate.systems.gpsins import augmented, ins, scenario
from navgate.systems.gpsins import filter as kf

ALL = (True, True, True, True)


def make_state(lat_deg=40.0, h=1500.0, v=(120.0, -80.0, 7.0), eul=(17.0, -11.0, 57.0)):
    x = np.zeros(10)
    x[0], x[1], x[2] = math.radians(lat_deg), 0.4, h
    x[3:6] = v
    x[6:10] = euler_to_quat(*(math.radians(a) for a in eul))
    return x


def random_spd(n, rng):
    a = rng.normal(size=(n, n))
    d = np.diag(np.concatenate([[1e-6, 1e-6], np.ones(n - 2)]))
    return d @ (a @ a.T + n * np.eye(n)) @ d


def test_layout():
    off, n = augmented.layout(ALL)
    assert n == 21 and list(off) == [9, 12, 15, 18]
    off, n = augmented.layout((False, True, False, True))
    assert n == 15 and list(off) == [-1, 9, -1, 12]
    assert augmented.state_names(off)[9:] == ["bgx", "bgy", "bgz", "sgx", "sgy", "sgz"]


def test_propagate_is_the_dense_phi_sandwich():
    """P' = Phi (P + G Q G' dt) Phi', Phi = I + F dt, computed densely in NumPy."""
    rng = np.random.default_rng(2)
    off, n = augmented.layout(ALL)
    x = make_state()
    f, w = np.array([1.5, -0.7, -9.0]), np.array([0.05, -0.02, 0.1])
    P = random_spd(n, rng)
    qa, qg = np.array([1e-4, 2e-4, 3e-4]), np.array([1e-7, 2e-7, 3e-7])
    dt = 0.01
    F = augmented.error_dynamics(x, f, w, off, n, ins.EARTH_WGS84)
    G = np.zeros((n, 6))
    G[:9] = kf.noise_input(x)
    phi = np.eye(n) + F * dt
    want = phi @ (P + G @ np.diag(np.concatenate([qa, qg])) @ G.T * dt) @ phi.T
    got = P.copy()
    F2 = augmented.propagate(got, x, f, w, dt, qa, qg, off, ins.EARTH_WGS84)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-20)
    np.testing.assert_array_equal(F2, F)
    np.testing.assert_array_equal(F[:9, :9], kf.error_dynamics(x, f, ins.EARTH_WGS84))


def test_update_is_the_textbook_joseph_form():
    rng = np.random.default_rng(4)
    off, n = augmented.layout(ALL)
    x = make_state()
    P = random_spd(n, rng)
    gps = x[:3] + np.array([3e-6, -2e-6, 15.0])
    sigma = np.array([20.0, 15.0, 30.0])
    hd = kf.measurement_scale(x)
    H = np.zeros((3, n))
    H[:, :3] = np.diag(hd)
    R = np.diag(sigma ** 2)
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    z = hd * (x[:3] - gps)
    ikh = np.eye(n) - K @ H
    want = ikh @ P @ ikh.T + K @ R @ K.T
    got = P.copy()
    dx, z2, S2 = kf.gps_update(got, x, gps, sigma)
    np.testing.assert_allclose(z2, z, rtol=1e-12)
    np.testing.assert_allclose(S2, S, rtol=1e-12)
    np.testing.assert_allclose(dx, K @ z, rtol=1e-9, atol=1e-18)
    scale = np.sqrt(np.outer(np.diag(want), np.diag(want)))
    assert np.max(np.abs(got - want) / scale) < 1e-10


def _cdot(x, xd):
    w = 2.0 * quat_multiply(quat_conjugate(x[6:10]), xd[6:10])[1:]
    return quat_to_dcm(x[6:10]) @ np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]],
                                             [-w[1], w[0], 0]])


def test_sensor_columns_match_the_nonlinear_ins():
    """A reading error df changes the INS's velocity rate by C df exactly (linear), and a
    gyro error dw changes the attitude error rate by -C dw (eps from E = I - C_hat C');
    so the bias columns are C and -C and the scale columns C diag(f + g e_z) and
    -C diag(w) (the errors the compensated readings carry, augmented.py)."""
    off, n = augmented.layout(ALL)
    x = make_state()
    f, w = np.array([1.5, -0.7, -9.0]), np.array([0.05, -0.02, 0.1])
    F = augmented.error_dynamics(x, f, w, off, n, ins.EARTH_SPHERE)
    C = quat_to_dcm(x[6:10])
    d0 = ins.derivatives(x, f, w, ins.EARTH_SPHERE)
    for j in range(3):
        e = np.zeros(3)
        e[j] = 1e-3
        dv = (ins.derivatives(x, f + e, w, ins.EARTH_SPHERE)[3:6] - d0[3:6]) / 1e-3
        np.testing.assert_allclose(F[3:6, off[0] + j], dv, rtol=1e-9, atol=1e-12)
        dep = f[j] + (augmented.G0 if j == 2 else 0.0)
        np.testing.assert_allclose(F[3:6, off[2] + j], dv * dep, rtol=1e-9, atol=1e-12)
        dh = ins.derivatives(x, f, w + e, ins.EARTH_SPHERE)
        edot = -(_cdot(x, dh) @ C.T + C @ _cdot(x, d0).T)
        eps_dot = np.array([edot[2, 1], edot[0, 2], edot[1, 0]]) / 1e-3
        np.testing.assert_allclose(F[6:9, off[1] + j], eps_dot, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(F[6:9, off[3] + j], eps_dot * w[j], rtol=1e-9, atol=1e-12)


def test_compensation_removes_what_the_update_estimated():
    """apply_correction moves the sensor estimates into the compensation, and compensate
    subtracts bias and scale error (the latter on f + g e_z and on w)."""
    off, n = augmented.layout(ALL)
    x = make_state()
    comp = np.zeros(12)
    dx = np.zeros(n)
    dx[9:21] = np.arange(1, 13) * 1e-3
    augmented.apply_correction(x.copy(), comp, dx, off)
    np.testing.assert_array_equal(comp, dx[9:21])
    f_m, w_m = np.array([0.5, -0.2, -9.7]), np.array([0.1, 0.2, -0.3])
    f_c, w_c = np.empty(3), np.empty(3)
    augmented.compensate(f_m, w_m, comp, f_c, w_c)
    dep = f_m + np.array([0.0, 0.0, augmented.G0])
    np.testing.assert_allclose(f_c, f_m - comp[0:3] - comp[6:9] * dep, rtol=1e-15)
    np.testing.assert_allclose(w_c, w_m - comp[3:6] - comp[9:12] * w_m, rtol=1e-15)


@pytest.fixture(scope="module")
def run0():
    return scenario.simulate(scenario.GpsInsConfig(seed=3))


def test_the_filter_finds_the_units_biases(run0):
    """Seed 3's unit: the final compensation (estimated bias) against the bias ImuModel drew.
    Each of the six must be within 4 posterior sigma (a sign error in a bias column or in
    the compensation would leave 2 b, many sigma for the observable ones), and the x and y
    gyro biases, which tilt the level aircraft and so show in the velocity, must be learnt:
    posterior sigma at most half the prior 0.003 deg/s (the z one, heading, is weakly
    observable on this flight)."""
    fw = run0.forward
    off = fw["off"]
    rec = run0.imu_record
    P = fw["p_post"][-1]
    comp = fw["comps"][-1]
    truth = np.concatenate([rec.accel_turn_on_bias, rec.gyro_turn_on_bias])
    est = comp[:6]
    sig = np.sqrt(np.concatenate([np.diag(P)[off[0]:off[0] + 3], np.diag(P)[off[1]:off[1] + 3]]))
    assert np.all(np.abs(est - truth) <= 4 * sig)
    assert np.all(sig[3:5] <= 0.5 * 0.003 * math.pi / 180)


def test_recomputed_interval_covariances_match_the_forward_pass(run0):
    fw = run0.forward
    dt = 1.0 / run0.cfg.rate_hz
    for e in (0, 150, 255, 299):
        k0, k1 = fw["ep_idx"][e], fw["ep_idx"][e + 1]
        Pj, Fs = augmented.interval_covariances(fw["p_post"][e], fw["states"], fw["fcs"],
                                                fw["wcs"], fw["qas"], fw["qgs"], dt, k0, k1,
                                                fw["off"])
        np.testing.assert_array_equal(Pj[-1], fw["p_prior"][e + 1])
        assert Fs.shape == (k1 - k0, 21, 21)


def test_blocks_follow_the_sensor_model_and_the_carry_flags():
    cfg = scenario.GpsInsConfig()
    P0 = np.eye(9)
    off, P, qa0, qg0, sfa, sfg = scenario.full_filter_setup(cfg, P0)
    assert P.shape == (21, 21) and sfa == sfg == 0.0
    qa_w, qg_w = scenario.white_densities(cfg.table1)
    np.testing.assert_allclose(qa0, qa_w)
    np.testing.assert_allclose(qg0, qg_w)
    # not carrying the gyro bias puts b^2 tau into the gyro noise instead
    off2, P2, _, qg2, _, sfg2 = scenario.full_filter_setup(
        replace(cfg, carry=(None, False, None, False)), P0)
    assert P2.shape == (15, 15) and off2[1] == -1
    b = cfg.table1.gyro_turn_on_drift_dps * math.pi / 180
    np.testing.assert_allclose(qg2, qg_w + b ** 2 * cfg.q_tau_s)
    assert sfg2 == cfg.table1.gyro_scale_in_flight
    # the ideal IMU has no sensor errors: nine states
    off3, P3, *_ = scenario.full_filter_setup(scenario.ideal_config(cfg), P0)
    assert P3.shape == (9, 9) and np.all(off3 == -1)
    with pytest.raises(ValueError):
        scenario.GpsInsConfig(carry=(True, True))
    with pytest.raises(ValueError):
        scenario.GpsInsConfig(filter="seed", smoother="rts")
    with pytest.raises(ValueError):
        scenario.GpsInsConfig(smoother="fixed")


def test_a_non_finite_fix_is_flagged_and_not_used(run0):
    """A fix with a NaN coordinate is counted in ``rejected`` and skipped (no update at that
    epoch: the posterior is the prior); every state stays finite."""
    fw = run0.forward
    gps = run0.gps
    lla = gps.lla.copy()
    lla[5, 1] = np.nan
    n_ep = 20
    k_end = int(gps.index[n_ep - 1])
    out = augmented.run(fw["states"][0].copy(), fw["p_post"][0].copy(),
                        np.ascontiguousarray(fw["wcs"][:k_end]),
                        np.ascontiguousarray(fw["fcs"][:k_end]), 1.0 / run0.cfg.rate_hz,
                        fw["ep_idx"][:n_ep + 1], lla[:n_ep], gps.valid[:n_ep],
                        np.full(3, 20.0), fw["qas"][0].copy(), fw["qgs"][0].copy(), 0.0, 0.0,
                        30.0, fw["off"])
    states, p_post, p_prior, rejected = out[0], out[6], out[7], out[12]
    assert rejected.sum() == 1 and rejected[5]
    np.testing.assert_array_equal(p_post[6], p_prior[6])
    assert not np.array_equal(p_post[7], p_prior[7])
    assert np.isfinite(states).all()
