"""Integrity monitor: counts every outcome by reason, declares divergence on a windowed NIS
above its chi-square bound, on consecutive gate rejections and on consecutive profiles the
DEM cannot explain, and then widens the search and reopens the filter covariance."""

import numpy as np
import pytest
from scipy.stats import chi2

from navgate.nav.eskf import UpdateResult
from navgate.trn.integrity import (
    DIVERGENCE,
    GATED,
    INCONSISTENT,
    IntegrityConfig,
    IntegrityMonitor,
)
from navgate.trn.pmf import PmfResult


class FakeCorrelator:
    def __init__(self):
        self.widened = []

    def reinitialise(self, widen):
        self.widened.append(widen)


def fix(accepted=True, reason="ok"):
    return PmfResult(accepted, reason)


def upd(nis, gate=13.8):
    return UpdateResult(nis <= gate, nis, gate, np.zeros(15))


def test_rejections_counted_by_reason_and_quiet_when_consistent():
    mon = IntegrityMonitor(FakeCorrelator())
    rng = np.random.default_rng(0)
    for _ in range(200):  # chi-square(2) NIS: a consistent filter never trips the monitor
        r = mon.review(fix(), upd(float(rng.chisquare(2))), rng.standard_normal(2), 10.0)
        assert r.event == "" or r.event == DIVERGENCE
    assert mon.events.get(DIVERGENCE, 0) <= 1  # 0.1 % false-alarm rate per window
    mon.review(fix(False, "flat terrain"), None, None, 10.0)
    mon.review(fix(False, "flat terrain"), None, None, 10.0)
    mon.review(fix(False, "multimodal"), None, None, 10.0)
    assert mon.counts["flat terrain"] == 2 and mon.counts["multimodal"] == 1
    assert mon.counts["applied"] + mon.counts.get(GATED, 0) == 200


def test_windowed_nis_above_its_bound_declares_divergence():
    cfg = IntegrityConfig(window=6, probability=0.999)
    corr = FakeCorrelator()
    mon = IntegrityMonitor(corr, cfg)
    bound = chi2.ppf(0.999, 12)
    assert mon.threshold == pytest.approx(bound)
    nis = bound / 6 * 1.1  # each one passes the filter's gate, the window does not
    events = [mon.review(fix(), upd(nis), np.array([30.0, -40.0]), 20.0) for _ in range(6)]
    assert [e.event for e in events[:5]] == [""] * 5
    assert events[5].event == DIVERGENCE
    assert np.allclose(events[5].inflate, np.outer([30.0, -40.0], [30.0, -40.0]))
    assert corr.widened == [cfg.widen]
    # the window restarts after a reinitialisation
    assert mon.review(fix(), upd(nis), np.zeros(2), 20.0).event == ""


def test_consecutive_gate_rejections_declare_divergence():
    mon = IntegrityMonitor(FakeCorrelator(), IntegrityConfig(max_consecutive_gated=3))
    assert mon.review(fix(), upd(50.0), np.array([100.0, 0.0]), 20.0).event == ""
    assert mon.review(fix(), upd(1.0), np.array([1.0, 0.0]), 20.0).event == ""  # resets
    assert mon.review(fix(), upd(50.0), np.array([100.0, 0.0]), 20.0).event == ""
    assert mon.review(fix(), upd(60.0), np.array([0.0, 110.0]), 20.0).event == ""
    r = mon.review(fix(), upd(70.0), np.array([120.0, 0.0]), 20.0)
    assert r.event == DIVERGENCE and mon.counts[GATED] == 4
    assert np.all(np.linalg.eigvalsh(r.inflate) > 0)


def test_profiles_the_dem_cannot_explain_reopen_the_search():
    corr = FakeCorrelator()
    mon = IntegrityMonitor(corr, IntegrityConfig(max_consecutive_inconsistent=3))
    for _ in range(2):
        assert mon.review(fix(False, INCONSISTENT), None, None, 50.0).event == ""
    r = mon.review(fix(False, INCONSISTENT), None, None, 50.0)
    assert r.event == DIVERGENCE
    assert np.allclose(r.inflate, np.eye(2) * 100.0**2)
    assert corr.widened and mon.counts[INCONSISTENT] == 3
