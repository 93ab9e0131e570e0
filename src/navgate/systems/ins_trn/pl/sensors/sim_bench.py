"""Amaranth-simulator runs of the sensor interfaces against the bit-level device models.

Each ``run_*`` builds the interface, attaches the device model (navgate.devices.bench), runs
for the given number of sample periods and returns what the interface delivered, its counters
and the model (served samples, timing violations). The clock frequency is a parameter: the
design counts cycles, the models check seconds, so a run at a scaled-down clock with a
proportionally smaller divider checks the same timing with fewer simulated cycles (the
default-configuration run at 100 MHz is in the tests too).

:func:`run_imu_emulated` runs SpiMasterImu against the gateware ADIS16500 emulator instead
(pins only between the two; the testbench only pushes samples and collects the output).
:func:`run_emulator_transactions` drives a gateware device emulator (ADIS16500, BMP390) with a
bare SPI PHY at its minimum half period, transaction by transaction, at the bit level.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from amaranth.hdl import Elaboratable, Module, Signal
from amaranth.sim import Simulator

from navgate.devices import adis16500, bmp390, tfluna
from navgate.devices.bench import CycleCounter, spi_slave_testbench, uart_source_testbench

from .adis16500_emulator import Adis16500Emulator
from .spi_master_baro import SpiMasterBaro
from .spi_master_imu import SpiMasterImu
from .spi_phy import MIN_HALF, SpiPhy
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


IMU_FIELDS = ("gx", "gy", "gz", "ax", "ay", "az", "temp", "diag", "cntr")


class ImuEmulatorPair(Elaboratable):
    """Emulator and master connected pin to pin, with a cycle counter."""

    def __init__(self, master):
        self.emu = Adis16500Emulator()
        self.master = master
        self.cycles = Signal(48)

    def elaborate(self, platform):
        m = Module()
        m.submodules.emu = emu = self.emu
        m.submodules.master = mst = self.master
        m.d.comb += [emu.sclk.eq(mst.sclk), emu.mosi.eq(mst.mosi), emu.cs_n.eq(mst.cs_n),
                     mst.miso.eq(emu.miso), mst.dr.eq(emu.dr)]
        m.d.sync += self.cycles.eq(self.cycles + 1)
        return m


def run_imu_emulated(samples, *, div, dr_sync, rate=0, cycles, gaps=None, push_after=None,
                     tick_cycles=1, dr_sync_at=0):
    """Adis16500Emulator -> pins -> SpiMasterImu (``cfg_spi_div`` = ``div``, data-ready mode if
    ``dr_sync``, else the timer with period ``rate``) at 100 MHz.

    Push ``samples`` (dicts of the emulator's SAMPLE_LAYOUT fields) into the emulator
    (``gaps[k]`` idle cycles before sample k; a sample waits while the emulator's FIFO is
    full) and collect the master's output for ``cycles``. ``push_after`` = (cycle, samples): a
    second batch pushed from that cycle on. Returns the samples delivered, their cycles, the
    CS_N falling cycles, push cycles and the counters of both sides. ``dr_sync_at``: the
    cycle at which ``cfg_dr_sync`` is set to ``dr_sync`` (0 until then)."""
    top = ImuEmulatorPair(SpiMasterImu(tick_cycles=tick_cycles))
    emu, mst = top.emu, top.master
    sim = Simulator(top)
    sim.add_clock(1e-8)
    res = {"got": [], "valid_at": [], "cs_fall_at": [], "push_at": []}

    async def push(ctx, batch, g):
        for k, s in enumerate(batch):
            await ctx.tick().repeat(max(1, g[k]))
            ctx.set(emu.samples.payload, s)
            ctx.set(emu.samples.valid, 1)
            await ctx.tick().until(emu.samples.ready)
            res["push_at"].append(ctx.get(top.cycles) - 1)
            ctx.set(emu.samples.valid, 0)

    async def pusher(ctx):
        await push(ctx, samples, gaps or [1] * len(samples))
        if push_after is not None:
            at, batch = push_after
            await ctx.tick().repeat(max(1, at - ctx.get(top.cycles)))
            await push(ctx, batch, [1] * len(batch))

    async def collect(ctx):
        async for (_v,) in ctx.posedge(mst.o.valid):
            while True:
                res["valid_at"].append(ctx.get(top.cycles))
                res["got"].append({n: ctx.get(getattr(mst.o.payload, n))
                                   for n in IMU_FIELDS})
                await ctx.tick()
                if not ctx.get(mst.o.valid):
                    break

    async def cs(ctx):
        async for (_c,) in ctx.negedge(mst.cs_n):
            res["cs_fall_at"].append(ctx.get(top.cycles))

    async def main(ctx):
        ctx.set(mst.cfg_spi_div, div)
        if rate:
            ctx.set(mst.cfg_rate, rate)
        ctx.set(mst.o.ready, 1)
        if dr_sync_at:
            await ctx.tick().repeat(dr_sync_at)
        ctx.set(mst.cfg_dr_sync, dr_sync)
        await ctx.tick().repeat(cycles - dr_sync_at)
        res.update({n: ctx.get(getattr(emu, n)) for n in ("bursts", "underruns", "dropped")})
        res.update({n: ctx.get(getattr(mst, n)) for n in
                    ("sample_count", "error_count", "sensor_error")})

    sim.add_testbench(pusher, background=True)
    sim.add_testbench(collect, background=True)
    sim.add_testbench(cs, background=True)
    sim.add_testbench(main)
    sim.run()
    return res


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


class _PhyBench(Elaboratable):
    """An emulator driven by a bare SpiPhy (half period MIN_HALF) and a CS_N signal."""

    def __init__(self, emulator, width: int):
        self.emu = emulator
        self.phy = SpiPhy(width)
        self.cs_n = Signal(init=1)

    def elaborate(self, platform):
        m = Module()
        m.submodules.emu, m.submodules.phy = self.emu, self.phy
        m.d.comb += [self.emu.sclk.eq(self.phy.sclk), self.emu.mosi.eq(self.phy.mosi),
                     self.emu.cs_n.eq(self.cs_n), self.phy.miso.eq(self.emu.miso),
                     self.phy.half.eq(MIN_HALF)]
        return m


def run_emulator_transactions(emulator, width: int, push, transactions, *, ready: str,
                              counters=()) -> dict:
    """Push ``push`` into the emulator's ``samples``, then run ``transactions`` (lists of
    ``width``-bit words sent, CS_N low around each). Returns ``words`` (read, per
    transaction), ``ready`` (the data-ready output ``ready`` before, during and after each
    transaction) and the emulator's ``counters`` at the end."""
    b = _PhyBench(emulator, width)
    sim = Simulator(b)
    sim.add_clock(1e-8)
    out = {"words": [], "ready": []}
    pin = getattr(b.emu, ready)

    async def main(ctx):
        for sample in push:
            ctx.set(b.emu.samples.payload, sample)
            ctx.set(b.emu.samples.valid, 1)
            await ctx.tick()
        ctx.set(b.emu.samples.valid, 0)
        await ctx.tick().repeat(4)
        for tx_words in transactions:
            level = [ctx.get(pin)]
            ctx.set(b.cs_n, 0)
            await ctx.tick().repeat(6)
            level.append(ctx.get(pin))
            words = []
            for tx in tx_words:
                ctx.set(b.phy.start, 1)
                ctx.set(b.phy.tx, tx)
                await ctx.tick()
                ctx.set(b.phy.start, 0)
                await ctx.tick().until(b.phy.done)
                words.append(ctx.get(b.phy.rx))
            await ctx.tick().repeat(4)
            ctx.set(b.cs_n, 1)
            await ctx.tick().repeat(8)
            level.append(ctx.get(pin))
            out["words"].append(words)
            out["ready"].append(level)
        out.update({n: ctx.get(getattr(b.emu, n)) for n in counters})

    sim.add_testbench(main)
    sim.run()
    return out
