"""The rtl engine (ins_engines gateware in Verilator, driven call by call) equals the fp32
engine bit for bit: every logged state, sigma and P_NE word, and every state register (nav,
compensation, biases, the 120 P elements and their compensation words) at the end; then
directed TRN updates (applied, rejected by the gate, singular S) with their outcomes and
every register after each."""

from __future__ import annotations

import pytest

from navgate.systems.ins_trn.pl.nav_engines import engine_image

#: cycles per IMU sample (propagate + start), asserted in test_engines.py
PER_SAMPLE = 639


def _fly_both(check, duration):
    stream, cfg, run, engs = check.fly("rtl", duration)
    # the run reports the gateware's cycles: at least the propagate program's per sample
    per_sample = engine_image("ins_engines").cycles("propagate") + 1
    assert run.hardware["engine_cycles"] >= engs["rtl"].samples * per_sample > 0
    check.directed_updates(engs, "rtl")
    # the inflated P reaches the gateware: the next samples propagate it in both engines
    for name in ("fp32", "rtl"):
        engs[name].propagate(stream.gyro_words[-3:], stream.accel_words[-3:])
    check.same_registers(engs, "rtl")
    assert engs["rtl"].samples == engs["fp32"].samples == round(duration * cfg.imu_rate_hz) + 3
    link = engs["rtl"].link
    engs["rtl"].close()
    return run, link


def test_rtl_engine_equals_fp32_60s_flight(against_fp32):
    """Issue 10's target: 60 s of the default mission with the gateware in the loop (native
    Verilator model), every logged state, P, the fix decisions and every register equal to
    the fp32 engine's, TRN fixes included."""
    run, link = _fly_both(against_fp32, 60.0)
    assert sum(run.accepted.values()) > 10
    assert link.cycles_run >= 24_000 * PER_SAMPLE


@pytest.mark.slow
def test_rtl_engine_equals_fp32_whole_default_flight(against_fp32):
    """The whole 10-minute default flight (240,000 IMU samples) through the gateware."""
    _fly_both(against_fp32, 600.0)
