"""Amaranth-simulator runs of the sensor interfaces against the bit-level device models.

Each ``run_*`` builds the interface, attaches the device model (navgate.devices.bench), runs
for the given number of sample periods and returns what the interface delivered, its counters
and the model (served samples, timing violations). The clock frequency is a parameter: the
design counts cycles, the models check seconds, so a run at a scaled-down clock with a
proportionally smaller divider checks the same timing with fewer simulated cycles (the
default-configuration run at 100 MHz is in the tests too).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from amaranth.sim import Simulator

from navgate.devices import adis16500, bmp390, tfluna
from navgate.devices.bench import CycleCounter, spi_slave_testbench, uart_source_testbench

from .spi_master_baro import SpiMasterBaro
from .spi_master_imu import SpiMasterImu
from .uart_rx_lidar import UartRxLidar


@dataclass
class BenchRun:
    got: list = field(default_factory=list)  #: delivered payloads (dicts)
    counters: dict = field(default_factory=dict)
    model: object = None
    first_valid_cycle: int | None = None
    first_cs_cycle: int | None = None
    flag_rises: int = 0  #: rising edges of ``sensor_error`` (lidar: its pulses + timed_out)


def _payload(ctx, port, names):
    return {n: ctx.get(getattr(port.payload, n)) for n in names}


def run_imu(stream: adis16500.ImuStream, periods: int, *, clk_hz: float = 6e6, div: int = 2,
            rate: int = 1300, tick_cycles: int = 1, ready=True) -> BenchRun:
    dut = SpiMasterImu(tick_cycles=tick_cycles)
    model = adis16500.Adis16500Model(stream)
    return _run_spi(dut, model, periods * rate * tick_cycles, clk_hz, div, rate,
                    ["diag", "gx", "gy", "gz", "ax", "ay", "az", "temp", "cntr"], ready)


def run_baro(stream: bmp390.BaroStream, periods: int, *, clk_hz: float = 30e6, div: int = 2,
             rate: int = 700, tick_cycles: int = 1) -> BenchRun:
    dut = SpiMasterBaro(tick_cycles=tick_cycles)
    model = bmp390.Bmp390Model(stream)
    # start-up (write + 70-byte read) takes about 75 bytes of 17 half periods
    startup = (div + 1) * 17 * 80
    return _run_spi(dut, model, periods * rate * tick_cycles + startup, clk_hz, div, rate,
                    ["up", "ut", "nvm"], True)


def _run_spi(dut, model, cycles, clk_hz, div, rate, names, ready):
    top = CycleCounter(dut)
    sim = Simulator(top)
    sim.add_clock(1.0 / clk_hz)
    run = BenchRun(model=model)
    sim.add_testbench(spi_slave_testbench(model, dut.cs_n, dut.sclk, dut.mosi, dut.miso,
                                          top.cycles, clk_hz), background=True)

    async def collect(ctx):
        async for (_valid,) in ctx.posedge(dut.o.valid):
            if run.first_valid_cycle is None:
                run.first_valid_cycle = ctx.get(top.cycles)
            run.got.append(_payload(ctx, dut.o, names))
            while True:  # back-to-back samples (a FIFO draining): take one per cycle
                await ctx.tick()
                if not ctx.get(dut.o.valid):
                    break
                run.got.append(_payload(ctx, dut.o, names))

    async def first_cs(ctx):
        async for (_cs,) in ctx.negedge(dut.cs_n):
            if run.first_cs_cycle is None:
                run.first_cs_cycle = ctx.get(top.cycles)

    async def main(ctx):
        ctx.set(dut.cfg_spi_div, div)
        ctx.set(dut.cfg_rate, rate)
        ctx.set(dut.o.ready, 1 if ready else 0)
        await ctx.tick().repeat(cycles)
        run.counters = {n: ctx.get(getattr(dut, n)) for n in
                        ("sample_count", "error_count", "sensor_error")}

    async def flag(ctx):
        async for (_flag,) in ctx.posedge(dut.sensor_error):
            run.flag_rises += 1

    sim.add_testbench(flag, background=True)
    if ready:
        sim.add_testbench(collect, background=True)
    sim.add_testbench(first_cs, background=True)
    sim.add_testbench(main)
    sim.run()
    return run


def run_lidar(stream: tfluna.LidarStream, *, div: int = 0, baud_error: float = 0.0,
              timeout_bits: int = 400, tail_s: float = 2e-3) -> BenchRun:
    """The UART source at ``BAUD * (1 + baud_error)`` into a receiver clocked at exactly
    16 * (div + 1) * BAUD."""
    clk_hz = tfluna.BAUD * 16 * (div + 1)
    dut = UartRxLidar(timeout_bits=timeout_bits)
    tr, end = tfluna.stream_transitions(stream, baud=tfluna.BAUD * (1 + baud_error))
    sim = Simulator(dut)
    sim.add_clock(1.0 / clk_hz)
    run = BenchRun(model=stream)
    names = ["dist", "strength", "temp", "reliable"]
    sim.add_testbench(uart_source_testbench(tr, dut.rx))

    async def collect(ctx):
        ctx.set(dut.cfg_div, div)
        ctx.set(dut.o.ready, 1)
        async for (_valid,) in ctx.posedge(dut.o.valid):
            run.got.append(_payload(ctx, dut.o, names))

    sim.add_testbench(collect, background=True)

    def flag(signal):
        async def count(ctx):
            async for (_v,) in ctx.posedge(signal):
                run.flag_rises += 1
        return count

    sim.add_testbench(flag(dut.sensor_error), background=True)
    sim.add_testbench(flag(dut.timed_out), background=True)

    async def tail(ctx):
        await ctx.delay(end + tail_s)
        run.counters = {n: ctx.get(getattr(dut, n)) for n in
                        ("byte_count", "frame_count", "checksum_errors", "framing_errors",
                         "unreliable_count", "timeout_count", "overrun_count", "timed_out")}

    sim.add_testbench(tail)
    sim.run()
    return run
