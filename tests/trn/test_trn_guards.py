"""The TRN library's guards: ProfileBuffer (constructor, add, shift),
IntegrityConfig/IntegrityMonitor, PmfConfig/PointMassCorrelator.correlate and TercomConfig
refuse nonsense with a ValueError naming the argument, never a ZeroDivisionError,
OverflowError or IndexError, and never a stored NaN."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.nav.earth import LocalTangent
from navgate.trn.dem import Dem
from navgate.trn.integrity import IntegrityConfig, IntegrityMonitor, Review
from navgate.trn.pmf import PmfConfig, PointMassCorrelator
from navgate.trn.profile import (
    ACCEPTED,
    REJECT_BARO,
    REJECT_RANGER,
    ProfileBuffer,
    ProfileSnapshot,
)
from navgate.trn.tercom import TercomConfig, TercomResult

NAN = float("nan")


def raises_naming(name, fn, *args, **kwargs):
    with pytest.raises(ValueError) as info:
        fn(*args, **kwargs)
    assert str(info.value).startswith(name), str(info.value)
    return str(info.value)


def sample(**changes):
    s = {"time": 10.0, "h_baro": 1500.0, "slant_range": 700.0, "range_valid": True,
         "roll": 0.0, "pitch": 0.0, "pos_n": 0.0, "pos_e": 0.0}
    s.update(changes)
    return s


# -- ProfileBuffer ------------------------------------------------------------------------------

@pytest.mark.parametrize("name, kwargs", [
    ("depth", {"depth": 1}), ("depth", {"depth": 2.5}), ("min_spacing_m", {"min_spacing_m": -1}),
    ("max_tilt_rad", {"max_tilt_rad": 2.0}), ("max_gap_s", {"max_gap_s": 0.0}),
    ("max_gap_s", {"max_gap_s": NAN}),
])
def test_profile_buffer_constructor(name, kwargs):
    raises_naming(name, ProfileBuffer, **kwargs)


@pytest.mark.parametrize("name, change", [
    ("time", {"time": NAN}), ("roll", {"roll": NAN}), ("pitch", {"pitch": math.inf}),
    ("pos_n", {"pos_n": NAN}), ("pos_e", {"pos_e": -math.inf}),
])
def test_profile_add_refuses_and_stores_nothing(name, change):
    buf = ProfileBuffer()
    raises_naming(name, buf.add, **sample(**change))
    assert buf.count == 0 and not buf.counts


def test_profile_add_refuses_time_going_backwards():
    buf = ProfileBuffer()
    assert buf.add(**sample(time=10.0)) == ACCEPTED
    raises_naming("time", buf.add, **sample(time=9.0, pos_n=100.0))
    snap = buf.snapshot()
    assert len(snap) == 1 and snap.time[0] == 10.0


def test_sensor_defects_are_counted_rejections_never_stored():
    """A NaN barometer or ranger reading is a dropout, a negative range a damaged frame (a
    replayed log can hold one): counted, not stored (a negative range was stored before),
    and not an error, so a replay goes on."""
    buf = ProfileBuffer()
    assert buf.add(**sample(h_baro=NAN)) == REJECT_BARO
    assert buf.add(**sample(slant_range=NAN)) == REJECT_RANGER
    assert buf.add(**sample(slant_range=-5.0)) == REJECT_RANGER
    assert buf.counts == {REJECT_BARO: 1, REJECT_RANGER: 2} and buf.count == 0
    assert buf.add(**sample(slant_range=0.0)) == ACCEPTED  # zero is a range (on the ground)


def test_profile_shift_refuses_nan():
    buf = ProfileBuffer()
    buf.add(**sample())
    raises_naming("d_east", buf.shift, 1.0, NAN)
    raises_naming("now", buf.shift, 1.0, 1.0, now=NAN)
    assert buf.snapshot().pos_n[0] == 0.0


# -- IntegrityConfig / IntegrityMonitor -----------------------------------------------------------

@pytest.mark.parametrize("name, kwargs", [
    ("window", {"window": 0}),  # IndexError / chi2 of 0 dof before
    ("probability", {"probability": 1.5}), ("probability", {"probability": 1.0}),
    ("max_consecutive_gated", {"max_consecutive_gated": 0}),
    ("max_consecutive_inconsistent", {"max_consecutive_inconsistent": -1}),
    ("widen", {"widen": 0.5}), ("widen", {"widen": NAN}),
])
def test_integrity_config(name, kwargs):
    raises_naming(name, IntegrityConfig, **kwargs)


class _Upd:
    def __init__(self, nis, accepted=True):
        self.nis, self.accepted = nis, accepted


def test_integrity_review_refuses_nonsense():
    mon = IntegrityMonitor(object())
    ok = TercomResult(True, "ok")
    raises_naming("sigma_max_m", mon.review, ok, _Upd(1.0), [1.0, 2.0], sigma_max_m=NAN)
    raises_naming("update.nis", mon.review, ok, _Upd(-3.0), [1.0, 2.0])
    raises_naming("innovation", mon.review, ok, _Upd(1.0), [NAN, 2.0])
    raises_naming("config", IntegrityMonitor, object(), {"window": 6})
    assert mon.counts == {}
    assert mon.review(ok, _Upd(1.0), [1.0, 2.0]) == Review()
    # a refused update (S not positive in the fp32 engine) may carry any NIS: counted as gated
    assert mon.review(ok, _Upd(-3.0, accepted=False), [1.0, 2.0]) == Review()
    assert mon.counts == {"applied": 1, "rejected by chi-square gate": 1}


# -- PmfConfig / PointMassCorrelator --------------------------------------------------------------

@pytest.mark.parametrize("name, kwargs", [
    ("min_samples", {"min_samples": 0}), ("min_samples", {"min_samples": 3}),
    ("consistency_probability", {"consistency_probability": 1.2}),
    ("max_tail_mass", {"max_tail_mass": 2.0}), ("min_valid_fraction", {"min_valid_fraction": -0.1}),
    ("range_sigma_m", {"range_sigma_m": 0.0}),  # 1 / var = 1 / 0 in the likelihood before
    ("velocity_sigma_mps", {"velocity_sigma_mps": -0.3}),
    ("max_cells", {"max_cells": 1}),  # 2 * half / (max_cells - 1): ZeroDivisionError before
    ("refine_cells", {"refine_cells": 1}),
    ("grid_step_m", {"grid_step_m": 0.0}), ("k_sigma", {"k_sigma": 0.0}),
    ("max_half_width_m", {"max_half_width_m": 100.0, "min_half_width_m": 150.0}),
])
def test_pmf_config(name, kwargs):
    raises_naming(name, PmfConfig, **kwargs)


@pytest.fixture(scope="module")
def pmf():
    dem = Dem.default()
    return PointMassCorrelator(dem, LocalTangent(*dem.center, 0.0))


def test_pmf_correlate_refuses(pmf):
    n = 20
    good = ProfileSnapshot(np.full(n, 500.0), np.arange(n) * 50.0, np.zeros(n),
                           np.arange(n, dtype=float))
    bad_t = ProfileSnapshot(good.h_terrain, good.pos_n, good.pos_e, np.full(n, NAN))
    raises_naming("snapshot.time", pmf.correlate, bad_t, 10.0)
    raises_naming("sigma_max_m", pmf.correlate, good, -1.0)
    raises_naming("prior_cov", pmf.correlate, good, 10.0, prior_cov=-np.eye(2))
    raises_naming("prior_cov", pmf.correlate, good, 10.0, prior_cov=np.eye(1))


# -- TercomConfig ---------------------------------------------------------------------------------

@pytest.mark.parametrize("v", [0, 1, 2.5])
def test_tercom_min_samples(v):
    raises_naming("min_samples", TercomConfig, min_samples=v)
