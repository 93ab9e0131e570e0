"""Amaranth-simulator adapters for the bit-level device models (async testbenches).

The device models are pin-edge driven (:class:`navgate.devices.spi.SpiSlave`) or produce line
transitions (:func:`navgate.devices.tfluna.stream_transitions`); these adapters connect them to
an Amaranth simulation so that Python runs once per pin edge, not once per clock cycle:

* :class:`CycleCounter` - an Elaboratable wrapping the DUT with a free-running cycle counter,
  the testbench's clock for time stamps (time = cycles / clk_hz);
* :func:`spi_slave_testbench` - waits for changes of CS_N, SCLK, MOSI, hands them to the model
  and drives MISO;
* :func:`uart_source_testbench` - drives the RX line through the transitions with
  ``ctx.delay``.
"""

from __future__ import annotations

from amaranth.hdl import Elaboratable, Module, Signal


class CycleCounter(Elaboratable):
    """Wraps ``dut`` (as submodule ``dut``) with a 48-bit cycle counter ``cycles``."""

    def __init__(self, dut):
        self.dut = dut
        self.cycles = Signal(48)

    def elaborate(self, platform):
        m = Module()
        m.submodules.dut = self.dut
        m.d.sync += self.cycles.eq(self.cycles + 1)
        return m


def spi_slave_testbench(model, cs_n, sclk, mosi, miso, cycles, clk_hz: float):
    """An async testbench that runs ``model`` (a SpiSlave) on the pins."""

    from amaranth.sim import BrokenTrigger

    async def bench(ctx):
        ctx.set(miso, 1)
        while True:
            try:
                async for cs, sc, mo in ctx.changed(cs_n, sclk, mosi):
                    t = ctx.get(cycles) / clk_hz
                    ctx.set(miso, model.pins(t, cs, sc, mo))
            except BrokenTrigger:
                # a second change in the same time step (outputs settling through
                # combinational wiring): apply the settled levels at the same time
                t = ctx.get(cycles) / clk_hz
                ctx.set(miso, model.pins(t, ctx.get(cs_n), ctx.get(sclk), ctx.get(mosi)))

    return bench


def uart_source_testbench(transitions, rx, t0: float = 0.0):
    """An async testbench that drives ``rx`` through (time, level) transitions (seconds)."""

    async def bench(ctx):
        ctx.set(rx, 1)
        now = 0.0
        for t, level in transitions:
            t = t + t0
            if t > now:
                await ctx.delay(t - now)
                now = t
            ctx.set(rx, level)

    return bench
