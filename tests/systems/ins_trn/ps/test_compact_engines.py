"""The compact engines (``rtl-compact``: the register machine behind the banked engine's ports
in Verilator; ``fpga-sim-compact``: the whole PL carrying it) equal the fp32 engine bit for
bit over the default mission: every logged state, sigma and P_NE word, every update and fix
decision, every register, then directed TRN updates (applied, gated, singular S) and the
covariance inflation."""

from __future__ import annotations

import pytest

from navgate.systems.ins_trn.pl.register_engine import register_engine_image
from navgate.systems.ins_trn.pl.sequencer import job_cycles


def _fly(check, name, duration):
    stream, cfg, run, engs = check.fly(name, duration)
    check.directed_updates(engs, name)
    assert engs[name].samples == engs["fp32"].samples
    return stream, cfg, run, engs


def test_rtl_compact_equals_fp32(against_fp32):
    _, cfg, run, engs = _fly(against_fp32, "rtl-compact", 2.0)
    # the run reports the register machine's cycles: the propagate entry's per sample
    per_sample = register_engine_image().cycles("propagate") + 1
    assert run.hardware["engine_cycles"] >= round(2.0 * cfg.imu_rate_hz) * per_sample
    assert sum(run.accepted.values()) > 0
    engs["rtl-compact"].close()


@pytest.mark.slow
def test_rtl_compact_equals_fp32_60s_flight(against_fp32):
    _, _, run, engs = _fly(against_fp32, "rtl-compact", 60.0)
    assert sum(run.accepted.values()) > 10
    engs["rtl-compact"].close()


@pytest.mark.slow
def test_rtl_compact_equals_fp32_whole_default_flight(against_fp32):
    """The whole 10-minute default flight (240,000 IMU samples, some 4 G cycles of the
    register machine; about 15 minutes)."""
    _, _, run, engs = _fly(against_fp32, "rtl-compact", 600.0)
    assert sum(run.accepted.values()) > 100
    engs["rtl-compact"].close()


@pytest.mark.slow
def test_fpga_sim_compact_equals_fp32(against_fp32):
    _, cfg, run, engs = _fly(against_fp32, "fpga-sim-compact", 2.0)
    eng = engs["fpga-sim-compact"]
    # at least the sequencer's IMU job on the register machine per sample went by
    assert eng.samples * job_cycles(eng.image, "imu") <= run.hardware["simulated_cycles"]
    assert eng.image is register_engine_image()
    assert sum(run.accepted.values()) > 0
    eng.close()
