"""Seed 000 clk_rst_gen (navgate.systems.ins_trn.pl.clocking): the reset sequence in simulation
(lock wait, synchroniser, 8-cycle reset, re-assertion by the external reset), and the MMCM
settings against the 7-series limits."""

from __future__ import annotations

import pytest
from amaranth import Module, ResetSignal, Signal
from amaranth.sim import Simulator

from navgate.systems.ins_trn.pl.clocking import (
    INPUT_CLOCK_HZ,
    MMCM_PARAMETERS,
    SYSTEM_CLOCK_HZ,
    ClockResetGenerator,
)


def run_sequence(lock_cycles, events, cycles):
    gen = ClockResetGenerator(simulation=True, lock_cycles=lock_cycles)
    m = Module()
    m.submodules.gen = gen
    probe = Signal()
    m.d.comb += probe.eq(ResetSignal("sync"))
    trace = []

    async def testbench(ctx):
        for cycle in range(cycles):
            if cycle in events:
                ctx.set(gen.ext_rst_n, events[cycle])
            _, _, rst = await ctx.tick("por").sample(probe)
            trace.append(rst)

    sim = Simulator(m)
    sim.add_clock(1e-8, domain="sync")
    sim.add_testbench(testbench)
    sim.run()
    return trace


def test_reset_released_eight_cycles_after_lock_is_synchronised():
    trace = run_sequence(20, {}, 60)
    first_low = trace.index(0)
    # lock at cycle 20 (model), two synchroniser stages, 8 cycles held, one output register
    assert first_low == 20 + 2 + 8 + 1
    assert all(trace[:first_low]) and not any(trace[first_low:])


def test_external_reset_reasserts_and_releases_after_eight_cycles():
    # the button goes low at cycle 30 and high at 33: two synchroniser stages, the hold
    # counter and the output register make the reset rise at 34; it falls 2 + 8 + 1 cycles
    # after the button is released
    trace = run_sequence(5, {30: 0, 33: 1}, 70)
    assert trace[16:34] == [0] * 18
    assert trace[34:44] == [1] * 10 and not any(trace[44:])
    # even a one-cycle glitch of the button gives the full 8-cycle reset
    trace = run_sequence(5, {30: 0, 31: 1}, 70)
    assert trace[34:42] == [1] * 8 and not any(trace[42:])


def test_mmcm_settings_make_100_mhz_inside_the_vco_range():
    vco = INPUT_CLOCK_HZ * MMCM_PARAMETERS["CLKFBOUT_MULT_F"] / MMCM_PARAMETERS["DIVCLK_DIVIDE"]
    assert 600e6 <= vco <= 1200e6  # 7-series -1 speed grade (DS187)
    assert vco / MMCM_PARAMETERS["CLKOUT0_DIVIDE_F"] == SYSTEM_CLOCK_HZ
    assert MMCM_PARAMETERS["CLKIN1_PERIOD"] == pytest.approx(1e9 / INPUT_CLOCK_HZ)


def test_bad_parameters():
    with pytest.raises(ValueError):
        ClockResetGenerator(reset_cycles=0)
