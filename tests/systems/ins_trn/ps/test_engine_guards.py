"""The seed-000 engines' guards: every engine (reference, fp32, fp32-plain, rtl,
fpga-sim) refuses what it cannot use with a ValueError naming the argument, through the one
set of checks in :mod:`navgate.systems.ins_trn.ps.pl_interface` (check_setup, check_imu_words,
check_altitude, check_trn, check_inflate), and nothing reaches the registers.

The reference and the float32 models are built; the Verilator engines (rtl, fpga-sim) are
not (a build takes minutes): their ``propagate`` is called on a bare instance, which shows
the check runs before any simulator is touched (the update and inflate calls they inherit
from Fp32Engine)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from navgate.nav import eskf
from navgate.nav.calibration import ImuCalibration
from navgate.nav.earth import LocalTangent
from navgate.sim import sensors
from navgate.systems.ins_trn.ps.engine_registry import engine_class, engine_names
from navgate.systems.ins_trn.ps.fp32_engine import Fp32Engine
from navgate.systems.ins_trn.ps.pl_interface import EngineSetup, make_engine

NAN = float("nan")
LAT, LON, H = math.radians(46.5), math.radians(7.5), 1500.0
BUILT = ("reference", "fp32", "fp32-plain")


def setup(**changes) -> EngineSetup:
    cal = ImuCalibration(np.zeros(3), np.eye(3), np.zeros(3), np.eye(3), 1e-4, 1e-3)
    p0 = eskf.initial_covariance(pos_sigma=30.0, vel_sigma=0.5, att_sigma=0.01,
                                 accel_bias_sigma=0.01, gyro_bias_sigma=1e-4)
    s = EngineSetup(cal, eskf.FilterConfig.from_imu_spec(sensors.ADIS16500), 400.0,
                    np.array([LAT, LON, H, 50.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), p0,
                    np.zeros(3), np.zeros(3), LocalTangent(LAT, LON, H))
    return replace(s, **changes)


def raises_naming(name, fn, *args, **kwargs):
    with pytest.raises(ValueError) as info:
        fn(*args, **kwargs)
    assert str(info.value).startswith(name), str(info.value)
    return str(info.value)


@pytest.fixture(scope="module", params=BUILT)
def engine(request):
    return make_engine(request.param, setup())


def snapshot(e):
    return e.read_nav(), e.read_cov(), e.samples


def unchanged(e, before):
    nav, cov, samples = snapshot(e)
    np.testing.assert_array_equal(nav, before[0])
    np.testing.assert_array_equal(cov, before[1])
    assert samples == before[2]


# -- setup (every engine: PlEngine.__init__ runs check_setup) ---------------------------------

P_INDEFINITE = np.diag([1.0] * 14 + [-1.0])
P_NAN = np.diag([1.0] * 14 + [NAN])
BAD_SETUPS = {
    "rate 0": ("rate_hz", {"rate_hz": 0.0}),
    "rate nan": ("rate_hz", {"rate_hz": NAN}),
    "p0 nan": ("p0", {"p0": P_NAN}),
    "p0 indefinite": ("p0", {"p0": P_INDEFINITE}),
    "p0 shape": ("p0", {"p0": np.eye(9)}),
    "latitude 90": ("nav0[0]", {"nav0": np.array([math.pi / 2, LON, H, 0, 0, 0, 1, 0, 0, 0])}),
    "height -7000 km": ("nav0[2]", {"nav0": np.array([LAT, LON, -7e6, 0, 0, 0, 1, 0, 0, 0])}),
    "nav0 nan": ("nav0", {"nav0": np.array([LAT, LON, H, NAN, 0, 0, 1, 0, 0, 0])}),
    "zero quaternion": ("nav0[6:10]", {"nav0": np.array([LAT, LON, H, 0, 0, 0, 0, 0, 0, 0])}),
    "bias nan": ("bias_g0", {"bias_g0": np.array([0.0, NAN, 0.0])}),
}


@pytest.mark.parametrize("engine_name", BUILT)
@pytest.mark.parametrize("case", list(BAD_SETUPS), ids=list(BAD_SETUPS))
def test_setup_refused_by_every_engine(engine_name, case):
    name, change = BAD_SETUPS[case]
    raises_naming(name, make_engine, engine_name, setup(**change))


def test_rate_zero_is_not_a_zero_division_in_the_fp32_engine():
    # without the shared check the fp32 engine raised ZeroDivisionError in _write_config
    raises_naming("rate_hz", Fp32Engine, setup(rate_hz=0))


# -- IMU words ---------------------------------------------------------------------------------

GOOD = np.zeros((4, 3))
BAD_WORDS = {
    "nan gyro word": ("gyro_words", np.array([[0.0, NAN, 0.0]] * 4), GOOD),
    "inf accel word": ("accel_words", GOOD, np.array([[0.0, 0.0, math.inf]] * 4)),
    "two columns": ("gyro_words", np.zeros((4, 2)), GOOD),  # read out of bounds before
    "flat array": ("accel_words", GOOD, np.zeros(12)),
    "fewer accel samples": ("accel_words", GOOD, np.zeros((3, 3))),
}


NON_FINITE = ("nan gyro word", "inf accel word")


@pytest.mark.parametrize("case", list(BAD_WORDS), ids=list(BAD_WORDS))
def test_words_refused(engine, case):
    name, gw, aw = BAD_WORDS[case]
    before = snapshot(engine)
    if engine.name == "reference" and case in NON_FINITE:
        # the float64 engine holds the last good sample and counts the bad ones
        rejected, samples = engine.imu_samples_rejected, engine.samples
        engine.propagate(gw, aw)
        assert engine.imu_samples_rejected - rejected == 4 and engine.samples - samples == 4
        assert np.all(np.isfinite(engine.read_nav()))
        return
    raises_naming(name, engine.propagate, gw, aw)
    unchanged(engine, before)


@pytest.mark.parametrize("cls_path", ["rtl", "fpga-sim"])
@pytest.mark.parametrize("case", list(BAD_WORDS), ids=list(BAD_WORDS))
def test_simulated_engines_check_words_before_the_simulator(cls_path, case):
    cls = engine_class(cls_path)
    bare = object.__new__(cls)  # no simulator, no registers: a check after would fail here
    name, gw, aw = BAD_WORDS[case]
    raises_naming(name, cls.propagate, bare, gw, aw)


# -- Kalman updates ----------------------------------------------------------------------------

BAD_TRN = {
    "R = -1e9 I": ("cov", (1.0, 2.0), -1e9 * np.eye(2), 0.0),
    "R indefinite": ("cov", (1.0, 2.0), np.diag([25.0, -4.0]), 0.0),
    "R not symmetric": ("cov", (1.0, 2.0), np.array([[25.0, 10.0], [-10.0, 25.0]]), 0.0),
    "R nan": ("cov", (1.0, 2.0), np.array([[25.0, NAN], [NAN, 25.0]]), 0.0),
    "R 3x3": ("cov", (1.0, 2.0), np.eye(3), 0.0),
    "y nan": ("y_ne", (NAN, 2.0), 25 * np.eye(2), 0.0),
    "negative lag": ("lag_s", (1.0, 2.0), 25 * np.eye(2), -0.5),
    "nan lag": ("lag_s", (1.0, 2.0), 25 * np.eye(2), NAN),
}


@pytest.mark.parametrize("case", list(BAD_TRN), ids=list(BAD_TRN))
def test_trn_update_refused(engine, case):
    name, y, cov, lag = BAD_TRN[case]
    before = snapshot(engine)
    raises_naming(name, engine.update_trn, y, cov, lag)
    unchanged(engine, before)
    assert "trn" not in engine.accepted and "trn" not in engine.rejected


@pytest.mark.parametrize("name, h, sigma", [("h_meas", NAN, 1.0), ("sigma", 1500.0, -1.0),
                                            ("sigma", 1500.0, 0.0), ("sigma", 1500.0, NAN)])
def test_altitude_update_refused(engine, name, h, sigma):
    before = snapshot(engine)
    raises_naming(name, engine.update_altitude, h, sigma)
    unchanged(engine, before)


@pytest.mark.parametrize("d_p", [np.diag([NAN, 1.0]), -np.eye(2), np.diag([100.0, -1.0]),
                                 np.eye(3)], ids=["nan", "negative", "indefinite", "shape"])
def test_inflate_refused(engine, d_p):
    before = snapshot(engine)
    raises_naming("d_p", engine.inflate_p_horizontal, d_p)
    unchanged(engine, before)


def test_good_calls_still_work_and_agree(engine):
    """The guards refuse nonsense only: a sound fix is applied by every engine with the NIS
    of the float64 formula (to float32 precision)."""
    e = make_engine(engine.name, setup())
    e.propagate(np.zeros((8, 3)), np.tile([0.0, 0.0, -9806.65], (8, 1)))
    p = e.read_p_horizontal()
    y, r = np.array([3.0, -2.0]), np.diag([25.0, 25.0])
    out = e.update_trn(y, r, 0.0)
    s = p + r
    nis = float(y @ np.linalg.solve(s, y))
    assert out.accepted
    assert out.nis == pytest.approx(nis, rel=1e-5)  # float32: 2^-24 per op, a few ops
    e.inflate_p_horizontal(np.diag([4.0, 9.0]))


# -- every registered engine shares the checks ----------------------------------------------------

CALLS = {
    "propagate": ("gyro_words", (np.zeros((4, 2)), np.zeros((4, 3)))),
    "update_trn": ("cov", ((1.0, 2.0), -1e9 * np.eye(2), 0.0)),
    "update_altitude": ("sigma", (1500.0, -1.0)),
    "inflate_p_horizontal": ("d_p", (np.diag([NAN, 1.0]),)),
}


@pytest.mark.parametrize("engine_name", engine_names())
@pytest.mark.parametrize("method", list(CALLS))
def test_every_registered_engine_checks_before_it_acts(engine_name, method):
    """Each registered engine class (engine_registry; a new one too), called on a bare
    instance (no registers, no simulator, no filter): the shared check refuses before
    anything else is touched."""
    cls = engine_class(engine_name)
    name, args = CALLS[method]
    raises_naming(name, getattr(cls, method), object.__new__(cls), *args)
