"""Sensor models: seed-000 word format, noise statistics against the specification,
calibration round trip, barometer and ranger behaviour, seeding."""

import math

import numpy as np
import pytest

from navgate.nav.calibration import ImuCalibration
from navgate.sim import sensors as s

N = 200_000


def test_imu_words_use_seed_lsbs_and_saturate_with_a_count():
    spec = s.ImuSpec(name="q", gyro_arw=0, gyro_bias_instability=0, gyro_turn_on_sigma=0,
                     accel_vrw=0, accel_bias_instability=0, accel_turn_on_sigma=0,
                     scale_factor_sigma=0, misalignment_sigma=0, factory_gyro_bias_sigma=0,
                     factory_accel_bias_sigma=0)
    gyro = np.array([[0.00625 * math.pi / 180 * 3, 0.0, 10.0]])  # 3 LSB, 0, far beyond range
    accel = np.array([[-9.80665, 1.25e-3 * 9.80665 * 2.4, 0.0]])
    rec = s.ImuModel(spec, seed=1).measure(gyro, accel)
    assert rec.gyro_words.dtype == np.int16
    assert rec.gyro_words.tolist() == [[3, 0, 32767]]
    assert rec.accel_words.tolist() == [[-800, 2, 0]]  # -1 g = -800 LSB of 1.25 mg
    assert rec.saturated == 1
    g, a = rec.calibration.apply(rec.gyro_words, rec.accel_words)
    assert math.isclose(g[0, 0], 3 * s.GYRO_LSB_RAD_S)


def test_imu_noise_matches_random_walk_specification():
    spec = s.ImuSpec(name="noise", gyro_bias_instability=0, gyro_turn_on_sigma=0,
                     accel_bias_instability=0, accel_turn_on_sigma=0, quantize=False)
    rec = s.ImuModel(spec, rate_hz=400, seed=7).measure(np.zeros((N, 3)), np.zeros((N, 3)))
    g, a = rec.calibration.apply(rec.gyro_words, rec.accel_words)
    sigma_g = spec.gyro_arw / math.sqrt(1 / 400)
    sigma_a = spec.accel_vrw / math.sqrt(1 / 400)
    # sample std of N normal draws has relative standard error 1/sqrt(2N) = 0.16 %: 5 sigma
    tol = 5 / math.sqrt(2 * N)
    assert np.allclose(g.std(axis=0) / sigma_g, 1.0, atol=tol)
    assert np.allclose(a.std(axis=0) / sigma_a, 1.0, atol=tol)


def test_calibration_removes_scale_misalignment_and_factory_bias():
    spec = s.ImuSpec(name="cal", gyro_arw=0, gyro_bias_instability=0, gyro_turn_on_sigma=0,
                     accel_vrw=0, accel_bias_instability=0, accel_turn_on_sigma=0,
                     scale_factor_sigma=5e-3, misalignment_sigma=2e-3, quantize=False)
    rng = np.random.default_rng(2)
    gyro = rng.uniform(-1, 1, (100, 3))
    accel = rng.uniform(-20, 20, (100, 3))
    rec = s.ImuModel(spec, seed=3).measure(gyro, accel)
    raw_g = rec.gyro_words * spec.gyro_lsb
    assert np.abs(raw_g - gyro).max() > 1e-3  # the raw words really are distorted
    g, a = rec.calibration.apply(rec.gyro_words, rec.accel_words)
    assert np.allclose(g, gyro, atol=1e-12) and np.allclose(a, accel, atol=1e-10)


def test_calibration_from_seed_parts_and_bad_matrices():
    mis = np.array([[0, 1e-3, 0], [0, 0, -2e-3], [5e-4, 0, 0]])
    cal = ImuCalibration.from_parts(gyro_scale=[1.01, 0.99, 1.0], gyro_misalignment=mis)
    assert np.allclose(cal.gyro_matrix, np.diag([1.01, 0.99, 1.0]) @ (np.eye(3) + mis))
    with pytest.raises(ValueError, match="singular"):
        ImuCalibration(gyro_matrix=np.zeros((3, 3)))
    with pytest.raises(ValueError):
        ImuCalibration(accel_bias=[np.nan, 0, 0])


def test_turn_on_bias_is_a_constant_and_in_run_bias_has_the_specified_spread():
    spec = s.ImuSpec(name="b", gyro_arw=0, accel_vrw=0, scale_factor_sigma=0,
                     misalignment_sigma=0, factory_gyro_bias_sigma=0, factory_accel_bias_sigma=0,
                     gyro_bias_tau=1.0, quantize=False)
    rec = s.ImuModel(spec, rate_hz=400, seed=11).measure(np.zeros((N, 3)), np.zeros((N, 3)))
    in_run = rec.gyro_bias - rec.gyro_turn_on_bias
    # tau = 1 s over 500 s: ~500 independent correlation times per axis, 1500 in all
    assert math.isclose(in_run.std(), spec.gyro_bias_instability, rel_tol=5 / math.sqrt(1500))


def test_same_seed_same_numbers_different_seed_different_numbers():
    x = np.zeros((1000, 3))
    a = s.ImuModel(seed=5).measure(x, x).gyro_words
    b = s.ImuModel(seed=5).measure(x, x).gyro_words
    c = s.ImuModel(seed=6).measure(x, x).gyro_words
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_isa_altitude_inverts_pressure_and_baro_noise_in_metres():
    h = np.array([-100.0, 0.0, 1000.0, 5000.0])
    assert np.allclose(s.isa_altitude(s.isa_pressure(h)), h, atol=1e-9)
    assert math.isclose(s.isa_pressure(0.0), 101325.0)
    assert math.isclose(s.isa_pressure(1000.0), 89874.6, rel_tol=1e-4)  # ISA table
    baro = s.Barometer(s.BaroSpec(offset_sigma_pa=0, drift_pa_per_sqrt_s=0), seed=1)
    t = np.arange(N) / 25.0
    rec = baro.measure(t, np.zeros(N))
    assert math.isclose(rec.altitude.std(), baro.altitude_noise_m, rel_tol=5 / math.sqrt(2 * N))


def test_ranger_range_limits_dropouts_and_tilt():
    t = np.arange(10_000) * 0.1
    agl = np.where(np.arange(t.size) % 2 == 0, 5.0, 20.0)  # 20 m is beyond a TF-Luna's 8 m
    rec = s.Ranger(s.TF_LUNA, seed=2).measure(t, agl, np.zeros(t.size), np.zeros(t.size))
    assert np.all(rec.status[1::2] == s.RANGE_OUT_OF_RANGE)
    ok = rec.status[::2] == s.RANGE_OK
    drop = rec.status[::2] == s.RANGE_DROPOUT
    assert np.all(ok | drop) and np.all(np.isnan(rec.slant_range[~rec.valid]))
    # 5000 trials at p = 1 %: 5-sigma binomial band
    assert abs(drop.mean() - 0.01) < 5 * math.sqrt(0.01 * 0.99 / 5000)
    # noise at 5 m: sigma = max(6 cm, 2 % * 5 m) = 10 cm
    r = rec.slant_range[::2][ok]
    assert math.isclose(r.std(), 0.10, rel_tol=0.05) and abs(r.mean() - 5.0) < 0.01
    ideal = s.Ranger(s.LONG_RANGE, ideal=True).measure(t[:3], np.full(3, 300.0),
                                                       np.full(3, 0.3), np.zeros(3))
    assert np.allclose(ideal.slant_range, 300.0 / math.cos(0.3))
    void = s.Ranger(s.LONG_RANGE, ideal=True).measure(t[:1], np.array([np.nan]), [0.0], [0.0])
    assert void.status[0] == s.RANGE_OUT_OF_RANGE


def test_sensor_records_through_the_device_encoders():
    """Baro raw words and ranger frames come from navgate.devices and decode back."""
    from navgate.devices import bmp390, tfluna
    from navgate.sim.sensors import LONG_RANGE, Barometer, Ranger

    t = np.arange(50) / 25.0
    rec = Barometer(seed=1).measure(t, np.full(50, 500.0))
    up, ut = Barometer.raw_words(rec)
    p, _ = bmp390.compensate(up, ut)
    assert np.max(np.abs(p - rec.pressure)) < 0.02  # one ADC count ~ 0.015 Pa
    r = Ranger(LONG_RANGE, seed=2).measure(t, np.full(50, 700.0), 0.0, 0.0)
    d = tfluna.decode_frames(r.frames(tfluna.LONG_RANGE_UNIT_M), tfluna.LONG_RANGE_UNIT_M)
    ok = r.valid
    assert np.all(np.abs(d["distance_m"][ok] - r.slant_range[ok]) <= 0.05 + 1e-9)
    assert np.all(d["reliable"] == ok) and np.all(d["checksum_ok"])


def test_gauss_markov_recursion_equals_scipy_lfilter():
    """The compiled first-order recursion is scipy.signal.lfilter's arithmetic (bit for bit)
    with the initial state phi * x, so seeded flights are unchanged by dropping the import."""
    from scipy.signal import lfilter

    rng = np.random.default_rng(7)
    w = rng.standard_normal((5000, 3))
    x0 = rng.standard_normal(3)
    phi = math.exp(-0.0025 / 3600.0)
    got = s._first_order(w, phi, x0)
    for axis in range(3):
        want = lfilter([1.0], [1.0, -phi], w[:, axis], zi=[phi * x0[axis]])[0]
        assert np.array_equal(got[:, axis], want)
