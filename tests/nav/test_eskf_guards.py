"""The reference ESKF's guards: FilterConfig, ErrorStateFilter's constructor,
propagate and every measurement update refuse what they cannot use with a ValueError naming
the argument, and a refused call leaves the filter as it was."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.nav import eskf

NAN = float("nan")
LAT = math.radians(46.5)
CFG = eskf.FilterConfig(1e-3, 1e-3, 1e-4, 300.0, 1e-5, 300.0)
P0 = eskf.initial_covariance(pos_sigma=30.0, vel_sigma=0.5, att_sigma=0.01,
                             accel_bias_sigma=0.01, gyro_bias_sigma=1e-4)


def nav(lat=LAT, h=1500.0):
    return np.array([lat, 0.13, h, 50.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])


def raises_naming(name, fn, *args, **kwargs):
    with pytest.raises(ValueError) as info:
        fn(*args, **kwargs)
    assert str(info.value).startswith(name), str(info.value)
    return str(info.value)


def make():
    return eskf.ErrorStateFilter(nav(), P0, CFG, rate_hz=400.0)


def state(f):
    return f.nav.copy(), f.p.copy(), dict(f.accepted), dict(f.rejected)


def assert_unchanged(f, before):
    np.testing.assert_array_equal(f.nav, before[0])
    np.testing.assert_array_equal(f.p, before[1])
    assert f.accepted == before[2] and f.rejected == before[3]


# -- FilterConfig ------------------------------------------------------------------------------

@pytest.mark.parametrize("name, index, value", [
    ("accel_bias_tau", 3, 0.0),  # exp(-dt / 0): ZeroDivisionError before
    ("gyro_bias_tau", 5, -300.0),
    ("accel_vrw", 0, -1e-3),
    ("gyro_arw", 1, NAN),
    ("gyro_bias_sigma", 4, math.inf),
])
def test_filter_config_refuses(name, index, value):
    args = [1e-3, 1e-3, 1e-4, 300.0, 1e-5, 300.0]
    args[index] = value
    raises_naming(name, eskf.FilterConfig, *args)


@pytest.mark.parametrize("p", [0.0, 1.0, 1.5, -0.1, NAN])
def test_gate_probability_must_be_a_probability(p):
    # 1.0 gives an infinite gate (nothing rejected), 1.5 a NaN gate (everything rejected)
    raises_naming("gate_probability", eskf.FilterConfig, 1e-3, 1e-3, 1e-4, 300.0, 1e-5, 300.0,
                  gate_probability=p)


# -- constructor ---------------------------------------------------------------------------------

@pytest.mark.parametrize("lat_deg", [90.0, -90.0, 89.95])
def test_latitude_at_a_pole_refused(lat_deg):
    msg = raises_naming("nav0[0]", eskf.ErrorStateFilter, nav(lat=math.radians(lat_deg)), P0,
                        CFG)
    assert "pole" in msg


def test_latitude_just_inside_the_margin_accepted():
    f = eskf.ErrorStateFilter(nav(lat=math.radians(89.89)), P0, CFG)
    assert f.nav[0] == math.radians(89.89)


@pytest.mark.parametrize("h", [-7e6, -25_000.0, 2e5])
def test_height_out_of_range_refused(h):
    raises_naming("nav0[2]", eskf.ErrorStateFilter, nav(h=h), P0, CFG)


@pytest.mark.parametrize("name, kwargs", [
    ("bias_a0", {"bias_a0": [0.0, NAN, 0.0]}),
    ("bias_g0", {"bias_g0": [0.0, 0.0]}),
    ("rate_hz", {"rate_hz": 0.0}),
    ("config", {"config": "adis16500"}),
])
def test_constructor_arguments_refused(name, kwargs):
    args = {"nav0": nav(), "p0": P0, "config": CFG, **kwargs}
    raises_naming(name, eskf.ErrorStateFilter, **args)


def test_negative_definite_p0_refused():
    raises_naming("p0", eskf.ErrorStateFilter, nav(), -P0, CFG)


# -- propagate -----------------------------------------------------------------------------------

@pytest.mark.parametrize("name, gyro, accel, k0, k1", [
    ("gyro", np.zeros((10, 2)), np.zeros((10, 3)), 0, 10),  # [k, 2] read out of bounds before
    ("accel", np.zeros((10, 3)), np.zeros((8, 3)), 0, 10),
    ("k0, k1", np.zeros((10, 3)), np.zeros((10, 3)), 0, 11),
    ("k0, k1", np.zeros((10, 3)), np.zeros((10, 3)), 5, 2),
    ("k0, k1", np.zeros((10, 3)), np.zeros((10, 3)), -1, 3),
])
def test_propagate_refuses_out_of_bounds_reads(name, gyro, accel, k0, k1):
    f = make()
    before = state(f)
    raises_naming(name, f.propagate, gyro, accel, k0, k1)
    assert_unchanged(f, before)


def test_propagate_refuses_a_mis_shaped_log_array():
    f = make()
    raises_naming("out_nav", f.propagate, np.zeros((4, 3)), np.zeros((4, 3)), 0, 4,
                  out_nav=np.zeros((4, 3)), out_sigma=np.zeros((4, 15)))


# -- measurement updates -------------------------------------------------------------------------

BAD_R = {
    "R = -1e9 I": -1e9 * np.eye(2),  # NIS below zero and an indefinite P before
    "indefinite": np.diag([25.0, -1.0]),
    "not symmetric": np.array([[25.0, 5.0], [0.0, 25.0]]),
    "nan": np.array([[NAN, 0.0], [0.0, 25.0]]),
    "3 x 3": 25.0 * np.eye(3),
}


@pytest.mark.parametrize("case", list(BAD_R), ids=list(BAD_R))
def test_trn_update_refuses_r(case):
    f = make()
    before = state(f)
    raises_naming("r_ne", f.update_position_offset, [3.0, -2.0], BAD_R[case])
    assert_unchanged(f, before)


@pytest.mark.parametrize("case", list(BAD_R), ids=list(BAD_R))
def test_generic_update_refuses_r(case):
    f = make()
    h = np.zeros((2, 15))
    h[0, 0] = h[1, 1] = 1.0
    r = BAD_R[case]
    before = state(f)
    raises_naming("r_matrix", f.update, [3.0, -2.0], h, r, "trn")
    assert_unchanged(f, before)


@pytest.mark.parametrize("lag", [-0.1, NAN, math.inf])
def test_trn_update_refuses_lag(lag):
    f = make()
    before = state(f)
    raises_naming("lag_s", f.update_position_offset, [3.0, -2.0], 25 * np.eye(2), lag)
    assert_unchanged(f, before)


def test_update_refuses_mis_shaped_h_and_nan_innovation():
    f = make()
    raises_naming("h_matrix", f.update, [1.0, 2.0], np.zeros((2, 9)), np.eye(2), "trn")
    raises_naming("y", f.update, [NAN, 2.0], np.zeros((2, 15)), np.eye(2), "trn")
    raises_naming("y_ne", f.update_position_offset, [1.0, 2.0, 3.0], np.eye(2))
    raises_naming("lat_fix", f.update_position_2d, math.radians(91.0), 0.13, np.eye(2))


@pytest.mark.parametrize("name, h, sigma", [("h_meas", NAN, 1.0), ("sigma", 1500.0, -2.0),
                                            ("sigma", 1500.0, NAN)])
def test_altitude_update_refused(name, h, sigma):
    f = make()
    before = state(f)
    raises_naming(name, f.update_altitude, h, sigma)
    assert_unchanged(f, before)


def test_sound_updates_still_match_the_formula():
    """The refactor into a checked ``update`` and an unchecked ``_update`` changes nothing for
    a sound fix: NIS = y' (P_NE + R)^-1 y exactly as the formula gives it."""
    f = make()
    y, r = np.array([30.0, -20.0]), np.diag([25.0, 36.0])
    s = f.p[:2, :2] + r
    res = f.update_position_offset(y, r)
    assert res.accepted
    assert res.nis == pytest.approx(float(y @ np.linalg.solve(s, y)), rel=1e-12)
    alt = f.update_altitude(1500.0, 2.0)
    assert alt.accepted and alt.nis >= 0
