"""API probes of issue 17: public constructors and functions reject what they cannot use with a
ValueError naming the argument (never a ZeroDivisionError, never a silent NaN later).

The guards themselves (navgate.nav.validate) are tested first, then every entry point that
calls them with the probes that broke it before: zero / NaN / non-unit quaternions, rates of
0, negative or NaN, latitudes beyond 90 deg, covariances that are not symmetric PSD, NaN
fixes, NaN profile times, negative sigmas, a NaN entering the attitude filters.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.nav import eskf, validate
from navgate.nav.earth import LocalTangent
from navgate.sim.sensors import ImuModel
from navgate.systems.attitude.complementary import run_complementary
from navgate.systems.attitude.estimate import AttitudeStream
from navgate.systems.attitude.mahony import NED_SI, run_mahony
from navgate.systems.gpsins import filter as gf
from navgate.trn.dem import Dem
from navgate.trn.profile import ProfileSnapshot
from navgate.trn.tercom import TercomConfig, TercomCorrelator

NAN = float("nan")
BAD_QUATS = {"zero": [0.0, 0, 0, 0], "nan": [NAN, 0, 0, 0], "non-unit": [2.0, 0, 0, 0],
             "short": [1.0, 0, 0]}


def raises_naming(name, fn, *args, **kwargs):
    with pytest.raises(ValueError) as info:
        fn(*args, **kwargs)
    assert str(info.value).startswith(name), str(info.value)
    return str(info.value)


# -- the guards -------------------------------------------------------------------------------

@pytest.mark.parametrize("q", list(BAD_QUATS.values()), ids=list(BAD_QUATS))
def test_unit_quaternion_guard(q):
    raises_naming("q", validate.unit_quaternion, "q", q)


def test_unit_quaternion_tolerance_is_far_above_rounding():
    q = np.array([1.0, 2.0, 3.0, 4.0]) / math.sqrt(30.0)
    np.testing.assert_array_equal(validate.unit_quaternion("q", q), q)
    raises_naming("q", validate.unit_quaternion, "q", q * (1 + 2e-6))


@pytest.mark.parametrize("value", [0.0, -1.0, NAN, math.inf, "x"])
def test_positive_guard(value):
    raises_naming("rate_hz", validate.positive, "rate_hz", value)


@pytest.mark.parametrize("p, word", [(-100 * np.eye(3), "semi-definite"),
                                     (np.array([[1.0, 0.5], [0.0, 1.0]]), "symmetric"),
                                     (np.array([[1.0, NAN], [NAN, 1.0]]), "non-finite"),
                                     (np.ones((2, 3)), "covariance")])
def test_covariance_guard(p, word):
    assert word in raises_naming("P", validate.covariance, "P", p)


def test_covariance_guard_accepts_rounding_level_asymmetry_and_zero():
    a = np.random.default_rng(0).normal(size=(15, 15))
    p = a @ a.T
    p[0, 1] += 1e-12 * np.abs(p).max()
    validate.covariance("P", p)
    validate.covariance("P", np.zeros((3, 3)))


def test_latitude_guard():
    raises_naming("lat", validate.latitude_rad, "lat", math.radians(90.001))
    assert validate.latitude_rad("lat", -math.pi / 2) == -math.pi / 2


def test_finite_array_names_the_index():
    msg = raises_naming("gyro", validate.finite_array, "gyro", [[0, 0, 0], [0, NAN, 0]])
    assert "(1, 1)" in msg


# -- attitude ---------------------------------------------------------------------------------

def level(n=50):
    return np.zeros((n, 3)), np.tile([0.0, 0.0, -9.80665], (n, 1)), np.arange(n) * 0.01


@pytest.mark.parametrize("q", list(BAD_QUATS.values()), ids=list(BAD_QUATS))
@pytest.mark.parametrize("runner", ["mahony", "complementary"])
def test_attitude_filters_reject_bad_q0(runner, q):
    g, a, t = level()
    fn = run_mahony if runner == "mahony" else run_complementary
    kwargs = {"params": NED_SI} if runner == "mahony" else {}
    raises_naming("q0", fn, g, a, t=t, q0=q, **kwargs)


@pytest.mark.parametrize("runner", ["mahony", "complementary"])
@pytest.mark.parametrize("arg", ["gyro", "acc", "t"])
def test_a_nan_is_caught_where_it_enters(runner, arg):
    """One NaN gyro row used to make every later Mahony output NaN."""
    g, a, t = level()
    {"gyro": g, "acc": a, "t": t}[arg][10, ...] = NAN
    fn = run_mahony if runner == "mahony" else run_complementary
    raises_naming(arg, fn, g, a, t=t)


def test_mahony_unstable_gain_and_bad_dt():
    g, a, t = level()
    raises_naming("kp", run_mahony, g, a, t=t, params=NED_SI.__class__(
        kp=1e300, ki=0.1, dt=0.01, gyro_scale=1.0, mag_sign=(1.0, 1.0, 1.0), accel_sign=-1.0))
    raises_naming("t", run_mahony, g, a, t=t[::-1])
    raises_naming("dt", run_mahony, g, a, dt=0.0)


def test_mahony_kernel_overflow_is_a_value_error_not_zero_division():
    g, a, t = level()
    g[5] = 1e200
    raises_naming("gyro", run_mahony, g, a, t=t)


def test_attitude_stream_arguments():
    raises_naming("method", AttitudeStream, "kalman")
    raises_naming("kp", AttitudeStream, "mahony", kp=-1)
    raises_naming("kp", AttitudeStream, "mahony", kp=100.0, gap_s=0.05)
    raises_naming("gain", AttitudeStream, "complementary", gain=2.0)


# -- error-state filter, sensors, geometry ----------------------------------------------------

def nav0(lat=0.6, q=(1.0, 0.0, 0.0, 0.0)):
    return np.array([lat, -1.4, 300.0, 50.0, 0.0, 0.0, *q])


CFG = eskf.FilterConfig(1e-3, 1e-3, 1e-4, 300.0, 1e-5, 300.0)


@pytest.mark.parametrize("q", [[0.0, 0, 0, 0], [NAN, 0, 0, 0], [2.0, 0, 0, 0]])
def test_eskf_rejects_bad_quaternion(q):
    raises_naming("nav0", eskf.ErrorStateFilter, nav0(q=q), np.eye(15), CFG)


def test_eskf_rejects_latitude_and_covariance_and_rate():
    raises_naming("nav0[0]", eskf.ErrorStateFilter, nav0(lat=2.0), np.eye(15), CFG)
    raises_naming("p0", eskf.ErrorStateFilter, nav0(), -100 * np.eye(15), CFG)
    asym = np.eye(15)
    asym[0, 1] = 0.5
    raises_naming("p0", eskf.ErrorStateFilter, nav0(), asym, CFG)
    from navgate.sim.sensors import ADIS16500

    for rate in (0.0, -1.0, NAN):
        raises_naming("rate_hz", eskf.ErrorStateFilter, nav0(), np.eye(15), CFG, rate_hz=rate)
        raises_naming("rate_hz", eskf.FilterConfig.from_imu_spec, ADIS16500, rate_hz=rate)


@pytest.mark.parametrize("rate", [0.0, -400.0, NAN])
def test_imu_model_rate(rate):
    with pytest.raises(ValueError):
        ImuModel(rate_hz=rate)


def test_local_tangent_and_trajectory_latitude():
    from navgate.sim import trajectory as tr

    raises_naming("lat0", LocalTangent, math.radians(91.0), 0.0)
    raises_naming("lat0", LocalTangent, NAN, 0.0)
    raises_naming("lat0", tr.generate, [tr.straight(5)], lat0=2.0, lon0=0.0, h0=100.0,
                  heading0=0.0, speed0=50.0)


# -- GPS/INS ----------------------------------------------------------------------------------

def gps_state():
    x = np.array([0.6, -1.4, 300.0, 50.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    return np.eye(gf.NX), x


def test_gps_update_rejects_nan_fix_and_negative_sigma():
    p, x = gps_state()
    p0 = p.copy()
    raises_naming("gps", gf.gps_update, p, x, np.array([NAN, -1.4, 300.0]), np.ones(3))
    raises_naming("sigma", gf.gps_update, p, x, np.array([0.6, -1.4, 300.0]),
                  np.array([1.0, -1.0, 1.0]))
    np.testing.assert_array_equal(p, p0)  # nothing entered the filter


def test_apply_correction_rejects_zero_quaternion():
    _, x = gps_state()
    x[6:10] = 0.0
    raises_naming("x", gf.apply_correction, x, np.zeros(9))


# -- TERCOM -----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def correlator():
    dem = Dem.default()
    return TercomCorrelator(dem, LocalTangent(*dem.center, 0.0))


def profile(n=60, nan_at=None):
    t = np.arange(n, dtype=float)
    if nan_at is not None:
        t[nan_at] = NAN
    return ProfileSnapshot(h_terrain=np.full(n, 300.0), pos_n=np.arange(n) * 30.0,
                           pos_e=np.zeros(n), time=t)


def test_tercom_rejects_nan_profile_time_and_negative_sigma(correlator):
    raises_naming("profile.time", correlator.correlate, profile(nan_at=30), 50.0)
    raises_naming("profile.time", correlator.correlate, profile(n=3, nan_at=2), 50.0)
    raises_naming("sigma_max_m", correlator.correlate, profile(), -5.0)


@pytest.mark.parametrize("field, value", [("k_sigma", -1.0), ("margin_m", NAN),
                                          ("grid_step_m", 0.0), ("min_valid_fraction", 1.5),
                                          ("cov_inflation", -1.0)])
def test_tercom_config(field, value):
    raises_naming(field, TercomConfig, **{field: value})
