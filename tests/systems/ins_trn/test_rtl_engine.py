"""The rtl engine (ins_engines gateware in Verilator, driven call by call) equals the fp32
engine bit for bit: every logged state, sigma and P_NE word, and every state register (nav,
compensation, biases, the 120 P elements and their compensation words) at the end; then
directed TRN updates (applied, rejected by the gate, singular S) with their outcomes and
every register after each."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.systems.ins_trn import flight
from navgate.systems.ins_trn.engine import make_engine
from navgate.systems.ins_trn.engines import engine_image
from navgate.systems.ins_trn.fp32_program import STATE_REGS
from navgate.systems.ins_trn.navigator import Navigator, engine_setup
from navgate.trn.dem import Dem

#: cycles per IMU sample (propagate + start), asserted in test_engines.py
PER_SAMPLE = 669


def _same_registers(engs):
    m1, m2 = engs["fp32"].m, engs["rtl"].m
    diff = [n for n in STATE_REGS
            if not (m1.get(n) == m2.get(n) or (math.isnan(m1.get(n)) and math.isnan(m2.get(n))))
            or math.copysign(1, m1.get(n)) != math.copysign(1, m2.get(n))]
    assert not diff, diff[:8]


def _fly_both(duration):
    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=duration, seed=1)
    _, _, stream = flight.record_stream(dem, cfg)
    runs, engs = {}, {}
    for name in ("fp32", "rtl"):
        eng = make_engine(name, engine_setup(stream.header, cfg))
        nav = Navigator(eng, cfg, t0=stream.header["t0"], dem=dem, use_trn=True)
        runs[name], engs[name] = nav.run(stream), eng
    a, b = runs["fp32"], runs["rtl"]
    # the run reports the gateware's cycles: at least the propagate program's per sample
    per_sample = engine_image("ins_engines").cycles("propagate") + 1
    assert b.hardware["engine_cycles"] >= engs["rtl"].samples * per_sample > 0
    assert np.array_equal(a.nav, b.nav) and np.array_equal(a.sigma, b.sigma)
    assert np.array_equal(a.p_ne, b.p_ne)
    assert a.accepted == b.accepted and a.rejected == b.rejected
    _same_registers(engs)
    # directed TRN updates after the flight: accepted, rejected by the gate, singular S
    cases = [((3.0, -2.0), np.diag([25.0, 25.0]), 0.05),
             ((5000.0, 4000.0), np.diag([1.0, 1.0]), 0.0),
             ((1.0, 1.0), np.full((2, 2), 1e12), 0.0)]  # S rounds to singular
    reasons = []
    for y, cov, lag in cases:
        a_out = engs["fp32"].update_trn(np.array(y), cov, lag)
        b_out = engs["rtl"].update_trn(np.array(y), cov, lag)
        assert a_out.accepted == b_out.accepted and a_out.reason == b_out.reason
        assert np.float32(a_out.nis).view(np.uint32) == np.float32(b_out.nis).view(np.uint32) \
            or (math.isnan(a_out.nis) and math.isnan(b_out.nis))
        assert np.array_equal(a_out.correction, b_out.correction)
        reasons.append(a_out.reason if not a_out.accepted else "applied")
        _same_registers(engs)
    assert reasons[0] == "applied" and "gate" in reasons[1] and "positive" in reasons[2], \
        reasons
    # the integrity monitor's covariance inflation (a PS register write) reaches the gateware:
    # the next samples propagate the inflated P in both engines
    for name in ("fp32", "rtl"):
        engs[name].inflate_p_horizontal(np.array([[400.0, 10.0], [10.0, 300.0]]))
    _same_registers(engs)
    for name in ("fp32", "rtl"):
        engs[name].propagate(stream.gyro_words[-3:], stream.accel_words[-3:])
    _same_registers(engs)
    assert engs["rtl"].samples == engs["fp32"].samples == round(duration * cfg.imu_rate_hz) + 3
    link = engs["rtl"].link
    engs["rtl"].close()
    return a, link


def test_rtl_engine_equals_fp32_60s_flight():
    """Issue 10's target: 60 s of the default mission with the gateware in the loop (native
    Verilator model), every logged state, P, the fix decisions and every register equal to
    the fp32 engine's, TRN fixes included."""
    run, link = _fly_both(60.0)
    assert sum(run.accepted.values()) > 10
    assert link.cycles_run >= 24_000 * PER_SAMPLE


@pytest.mark.slow
def test_rtl_engine_equals_fp32_whole_default_flight():
    """The whole 10-minute default flight (240,000 IMU samples) through the gateware."""
    _fly_both(600.0)
