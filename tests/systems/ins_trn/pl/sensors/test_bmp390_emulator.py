"""BMP390 emulator (gateware SPI slave) against SpiMasterBaro in the Amaranth simulator: pins
only between the two (synchronisers on both sides), INT-paced mode at the minimum and the
default divider and timer mode; every pushed (up, ut) comes out of the master once, in order,
with the emulator's NVM, and the compensation gives navgate.devices.bmp390.compensate_fp32
bit for bit; underruns are reads without drdy that the master counts as errors; the bytes on
MISO equal those of the Python bus model Bmp390Model for the same transactions."""

import numpy as np
import pytest
from amaranth.hdl import Elaboratable, Module, Signal
from amaranth.sim import Simulator

from navgate.devices import bmp390 as B
from navgate.devices.spi import drive_transfer
from navgate.gateware.verify import verify
from navgate.systems.ins_trn.pl.sensors.baro_compensation import BaroCompensation
from navgate.systems.ins_trn.pl.sensors.bmp390_emulator import (
    FIFO_DEPTH,
    INT_ROUND_TRIP,
    MIN_HALF,
    Bmp390Emulator,
    Bmp390Loopback,
)
from navgate.systems.ins_trn.pl.sensors.sensor_subsystem import SensorSubsystem
from navgate.systems.ins_trn.pl.sensors.sim_bench import run_emulator_transactions
from navgate.systems.ins_trn.pl.sensors.spi_master_baro import SAMPLE_LAST_ADDR, read_cycles

MIN_DIV = MIN_HALF - 1  # cfg_spi_div 2: SCLK half period 3 cycles
SAMPLE_BYTES = SAMPLE_LAST_ADDR + 3  # command + dummy + 0x00..0x09
#: INT rising (emulator pin) -> sample at the master's output: master INT synchroniser (2),
#: edge -> fire (1), WAIT -> START (1), START -> CS_N low (1), the read (CS_N low), CHECK (1)
INT_TO_SAMPLE_MIN = 5 + read_cycles(MIN_DIV, SAMPLE_BYTES) + 1
INT_TO_SAMPLE_DEFAULT = 5 + read_cycles(5, SAMPLE_BYTES) + 1
assert (INT_TO_SAMPLE_MIN, INT_TO_SAMPLE_DEFAULT) == (621, 1236)  # the figures in the docs
#: a part whose NVM differs from DEFAULT_NVM in every coefficient (exercises the NVM path)
PAR = {"T1": 27000, "T2": 19500, "T3": -6, "P1": 1100, "P2": -3000, "P3": 22, "P4": 1,
       "P5": 25900, "P6": 29000, "P7": 4, "P8": -9, "P9": 5000, "P10": 6, "P11": -55}


def _samples(n, seed, par=B.DEFAULT_NVM):
    """n raw samples: the range corners first, then seeded random pressures/temperatures."""
    rng = np.random.default_rng(seed)
    p0, p1 = B.PRESSURE_RANGE_PA
    t0, t1 = B.TEMPERATURE_RANGE_C
    p = np.concatenate([[p0, p1, p0, p1], rng.uniform(p0, p1, max(0, n - 4))])[:n]
    t = np.concatenate([[t0, t0, t1, t1], rng.uniform(t0, t1, max(0, n - 4))])[:n]
    up, ut = B.encode(p, t, par)
    return [{"up": int(a), "ut": int(b)} for a, b in zip(up, ut, strict=True)]


class _Pair(Elaboratable):
    def __init__(self, nvm=None, compensate=True, tick_cycles=1):
        from navgate.systems.ins_trn.pl.sensors.spi_master_baro import SpiMasterBaro

        self.emu = Bmp390Emulator(nvm)
        self.master = SpiMasterBaro(tick_cycles=tick_cycles)
        self.comp = BaroCompensation() if compensate else None
        self.cycles = Signal(48)

    def elaborate(self, platform):
        m = Module()
        m.submodules.emu, m.submodules.master = emu, mst = self.emu, self.master
        m.d.comb += [emu.sclk.eq(mst.sclk), emu.mosi.eq(mst.mosi), emu.cs_n.eq(mst.cs_n),
                     mst.miso.eq(emu.miso), mst.int_pin.eq(emu.int_pin)]
        if self.comp is not None:
            m.submodules.comp = self.comp
            m.d.comb += [self.comp.i.payload.eq(mst.o.payload), self.comp.i.valid.eq(mst.o.valid),
                         mst.o.ready.eq(self.comp.i.ready), self.comp.o.ready.eq(1)]
        else:
            m.d.comb += mst.o.ready.eq(1)
        m.d.sync += self.cycles.eq(self.cycles + 1)
        return m


def _run(samples, *, div, int_sync, rate=60000, cycles, gaps=None, par=None, push_at=0):
    """Push ``samples`` (gaps[k] idle cycles before sample k, from cycle ``push_at``), run
    ``cycles``; returns the raw and compensated outputs, their cycles, INT rising and CS_N
    falling cycles, and both sides' counters."""
    nvm = None if par is None else B.nvm_bytes(par)
    top = _Pair(nvm)
    emu, mst, comp = top.emu, top.master, top.comp
    sim = Simulator(top)
    sim.add_clock(1e-8)
    r = {"raw": [], "raw_at": [], "comp": [], "int_at": [], "cs_fall_at": []}

    async def pusher(ctx):
        await ctx.tick().repeat(max(1, push_at))
        for k, s in enumerate(samples):
            await ctx.tick().repeat(max(1, (gaps or [1] * len(samples))[k]))
            ctx.set(emu.samples.payload, s)
            ctx.set(emu.samples.valid, 1)
            await ctx.tick().until(emu.samples.ready)
            ctx.set(emu.samples.valid, 0)

    def edges(sig, key, neg=False):
        async def watch(ctx):
            async for (_v,) in (ctx.negedge(sig) if neg else ctx.posedge(sig)):
                r[key].append(ctx.get(top.cycles))
        return watch

    async def raw(ctx):
        async for (_v,) in ctx.posedge(mst.o.valid):
            r["raw_at"].append(ctx.get(top.cycles))
            r["raw"].append({n: ctx.get(getattr(mst.o.payload, n)) for n in ("up", "ut", "nvm")})

    async def compensated(ctx):
        async for (_v,) in ctx.posedge(comp.o.valid):
            r["comp"].append((ctx.get(comp.o.payload.p), ctx.get(comp.o.payload.t)))

    async def main(ctx):
        ctx.set(mst.cfg_spi_div, div)
        ctx.set(mst.cfg_rate, rate)
        ctx.set(mst.cfg_int_sync, int_sync)
        await ctx.tick().repeat(cycles)
        r.update({n: ctx.get(getattr(emu, n)) for n in ("served", "underruns")})
        r.update({n: ctx.get(getattr(mst, n)) for n in
                  ("sample_count", "error_count", "sensor_error", "nvm_valid")})

    for tb in (pusher, raw, compensated, edges(emu.int_pin, "int_at"),
               edges(mst.cs_n, "cs_fall_at", neg=True)):
        sim.add_testbench(tb, background=True)
    sim.add_testbench(main)
    sim.run()
    return r


def _check_delivered(r, samples, par):
    nvm = int.from_bytes(B.nvm_bytes(par), "little")
    assert r["raw"] == [s | {"nvm": nvm} for s in samples]
    p, t = B.compensate_fp32([s["up"] for s in samples], [s["ut"] for s in samples], par)
    assert r["comp"] == [(int(a), int(b)) for a, b in zip(p, t, strict=True)]


def test_int_mode_minimum_divider_random_samples():
    """30 samples (range corners + seeded random), a non-default NVM, INT mode at SCLK half
    period 3, pushed with random gaps (some in quick succession: the emulator FIFO holds up to
    4): every sample delivered once, in order, with the emulator's NVM, compensated bit for bit
    as compensate_fp32; one read per sample (+ the start-up write and NVM read); no errors;
    INT rising -> sample at the master's output exactly INT_TO_SAMPLE_MIN cycles."""
    n = 30
    samples = _samples(n, seed=51, par=PAR)
    rng = np.random.default_rng(52)
    gaps = [int(g) for g in rng.choice([1, 2, 300, 900, 1500], n)]
    r = _run(samples, div=MIN_DIV, int_sync=1, cycles=sum(gaps) + n * 700 + 5000, gaps=gaps,
             par=PAR)
    _check_delivered(r, samples, PAR)
    assert (r["served"], r["underruns"]) == (n, 0)
    assert (r["sample_count"], r["error_count"], r["sensor_error"]) == (n, 0, 0)
    assert len(r["cs_fall_at"]) == n + 2  # PWR_CTRL write, NVM read, one read per sample
    # the INT rising edge that each sample read answered: the last one before its CS_N falling
    reads = r["cs_fall_at"][2:]
    ints = [max(i for i in r["int_at"] if i < c) for c in reads]
    lat = [v - i for i, v in zip(ints, r["raw_at"], strict=True)]
    assert lat[1:] == [INT_TO_SAMPLE_MIN] * (n - 1)
    assert [c - i for i, c in zip(ints, reads, strict=True)][1:] == [5] * (n - 1)
    # back to back while samples were waiting: INT round trip after CS_N rising
    periods = np.diff(reads)
    assert periods.min() == read_cycles(MIN_DIV, SAMPLE_BYTES) + INT_ROUND_TRIP == 624
    assert np.count_nonzero(periods == periods.min()) >= 3


def test_int_mode_default_divider():
    """cfg_spi_div 5 (the default): 4 samples after start-up, two pairs pushed back to back:
    INT -> sample 1,236 cycles each; reads of waiting samples 1,239 cycles apart."""
    samples = _samples(4, seed=61)
    r = _run(samples, div=5, int_sync=1, cycles=4 * 1800 + 12000, gaps=[1, 1, 3000, 1],
             push_at=8000)
    _check_delivered(r, samples, B.DEFAULT_NVM)
    assert (r["served"], r["underruns"], r["error_count"]) == (4, 0, 0)
    reads = r["cs_fall_at"][2:]
    ints = [max(i for i in r["int_at"] if i < c) for c in reads]
    assert [v - i for i, v in zip(ints, r["raw_at"], strict=True)] == [INT_TO_SAMPLE_DEFAULT] * 4
    assert len(reads) == 4 and len(r["int_at"]) == 4
    assert [reads[1] - reads[0], reads[3] - reads[2]] == [
        read_cycles(5, SAMPLE_BYTES) + INT_ROUND_TRIP] * 2 == [1239] * 2


def test_int_mode_samples_waiting_before_startup():
    """Samples pushed before the master is up (emulator in sleep: INT low): after the
    PWR_CTRL write INT rises, the start-up NVM read consumes nothing, and the queued samples
    are then read once each, in order."""
    samples = _samples(FIFO_DEPTH, seed=62)
    r = _run(samples, div=MIN_DIV, int_sync=1, cycles=8000)
    _check_delivered(r, samples, B.DEFAULT_NVM)
    assert (r["served"], r["underruns"], r["error_count"]) == (FIFO_DEPTH, 0, 0)
    assert len(r["cs_fall_at"]) == FIFO_DEPTH + 2


def test_timer_mode_with_underruns():
    """Timer mode (INT ignored): reads every `rate` cycles; with no sample waiting the read
    gets STATUS 0x10 (no drdy): counted by the emulator (underruns) and by the master
    (error_count, sensor_error until the next good sample), never delivered; then delivery
    resumes in order."""
    rate = 1000
    samples = _samples(6, seed=63)
    # reads at ~1000, 2000, ... (the start-up runs first); the 6 samples: 3 at once, then 3
    # after a pause that leaves 3 reads without a sample
    gaps = [1, 1, 1, 6500, 1, 1]
    r = _run(samples, div=MIN_DIV, int_sync=0, rate=rate, cycles=12 * rate + 700, gaps=gaps)
    _check_delivered(r, samples, B.DEFAULT_NVM)
    nreads = len(r["cs_fall_at"]) - 2
    assert r["served"] == 6 and r["underruns"] == nreads - 6 and r["underruns"] >= 3, nreads
    assert (r["sample_count"], r["error_count"]) == (6, r["underruns"])
    assert r["sensor_error"] == 1  # the last reads underran (nothing pushed after)


def test_int_mode_ignores_a_fast_timer():
    """INT mode with BARO_RATE = 300 cycles (a timer that would read 20 times): only the 2
    pushed samples are read, no underruns."""
    samples = _samples(2, seed=64)
    r = _run(samples, div=MIN_DIV, int_sync=1, rate=300, cycles=10000, gaps=[1, 5000])
    _check_delivered(r, samples, B.DEFAULT_NVM)
    assert len(r["cs_fall_at"]) == 4 and (r["underruns"], r["error_count"]) == (0, 0)


def test_int_mode_failed_startup_retries_on_the_timer():
    """INT mode with no part on the bus (MISO pulled high: CHIP_ID reads 0xFF, INT never
    rises): the start-up fails, is counted, and is retried every BARO_RATE period."""
    from navgate.systems.ins_trn.pl.sensors.spi_master_baro import SpiMasterBaro

    dut = SpiMasterBaro(tick_cycles=1)
    sim = Simulator(dut)
    sim.add_clock(1e-8)
    falls = []

    async def cs(ctx):
        async for (_c,) in ctx.negedge(dut.cs_n):
            falls.append(1)

    async def main(ctx):
        ctx.set(dut.cfg_spi_div, MIN_DIV)
        ctx.set(dut.cfg_rate, 5000)
        ctx.set(dut.cfg_int_sync, 1)
        await ctx.tick().repeat(3 * 5000 + 4500)
        falls.append((ctx.get(dut.error_count), ctx.get(dut.nvm_valid),
                      ctx.get(dut.sensor_error)))

    sim.add_testbench(cs, background=True)
    sim.add_testbench(main)
    sim.run()
    # start-up (write + NVM read) at 0, retried after the timer at 5000, 10000, 15000
    assert falls == [1] * 8 + [(4, 0, 1)]


def _phy_run(push, transactions):
    out = run_emulator_transactions(Bmp390Emulator(), 8, push, transactions, ready="int_pin",
                                    counters=("served", "underruns"))
    ready = out.pop("ready")
    out["bytes"] = out.pop("words")
    out["int"] = [level[0] for level in ready] + [ready[-1][2]]  # before each, after the last
    return out


def _read(addr, n):
    return [0x80 | addr, 0] + [0] * n


def test_bytes_equal_the_bus_model():
    """Directed transactions at the bit level: a read in sleep mode, the PWR_CTRL write, the
    start-up read 0x00..0x45, sample reads 0x00..0x09, a partial read (0x00..0x03, consumes
    nothing), a read from DATA_0, OSR/ODR writes read back, a read wrapping past 0x7F, a
    soft reset and back: the emulator's MISO bytes equal Bmp390Model's (same samples, same
    word lists through drive_transfer; four sample reads serve the four samples). Then one
    more sample read with nothing waiting:
    STATUS 0x10 and the last sample's data (the model keeps serving its last sample)."""
    samples = _samples(4, seed=71)
    txs = [_read(0, 10), [0x1B, 0x33], _read(0, 0x46), _read(0, 10), _read(0, 4),
           _read(0, 10), _read(4, 6), [0x1C, 0x05, 0x1D, 0x02], _read(0x1B, 3),
           _read(0x7C, 6), _read(0, 10), [0x7E, 0xB6], _read(0, 10), [0x1B, 0x33]]
    stream = B.BaroStream(np.array([s["up"] for s in samples]),
                          np.array([s["ut"] for s in samples]))
    model = B.Bmp390Model(stream)
    want, t = [], 0.0
    for words in txs:
        rx, t = drive_transfer(model, words, 8, t0=t + 1e-6, half=100e-9, cs_setup=100e-9,
                               cs_hold=100e-9)
        want.append(rx)
    assert model.violations == [] and model.served == [0, 1, 2, 3]
    out = _phy_run(samples, txs + [_read(0, 10)])
    assert out["bytes"][:len(txs)] == want
    last = samples[3]
    assert out["bytes"][-1] == [0xFF, 0, 0x60, 0x01, 0, 0x10] + list(
        B.data_bytes(last["up"], last["ut"]))  # underrun: no drdy, the last data
    assert (out["served"], out["underruns"]) == (4, 1)
    # INT: low in sleep, high in normal mode while samples wait, low once all are served
    assert out["int"][0] == 0 and out["int"][2] == 1 and out["int"][-1] == 0


def test_sensor_subsystem_int_mode():
    """SensorSubsystem with the emulator on its barometer pins and BARO_CFG = int_sync |
    enable | div 2 (BARO_RATE left at 40,000 ticks: the timer would never fire in the run):
    the baro stream carries compensate_fp32 of each pushed sample, no errors."""
    samples = _samples(3, seed=81)

    class Top(Elaboratable):
        def __init__(self):
            self.emu = Bmp390Emulator()
            self.sub = SensorSubsystem(tick_cycles=100, calibrate=False)

        def elaborate(self, platform):
            m = Module()
            m.submodules.emu, m.submodules.sub = emu, sub = self.emu, self.sub
            m.d.comb += [emu.sclk.eq(sub.baro_sclk), emu.mosi.eq(sub.baro_mosi),
                         emu.cs_n.eq(sub.baro_cs_n), sub.baro_miso.eq(emu.miso),
                         sub.baro_int.eq(emu.int_pin)]
            return m

    top = Top()
    sub, emu = top.sub, top.emu
    sim = Simulator(top)
    sim.add_clock(1e-8)
    got = []

    async def pusher(ctx):
        for s in samples:
            await ctx.tick().repeat(1000)
            ctx.set(emu.samples.payload, s)
            ctx.set(emu.samples.valid, 1)
            await ctx.tick().until(emu.samples.ready)
            ctx.set(emu.samples.valid, 0)

    async def collect(ctx):
        async for (_v,) in ctx.posedge(sub.baro.valid):
            got.append((ctx.get(sub.baro.payload.p), ctx.get(sub.baro.payload.t)))

    async def main(ctx):
        ctx.set(sub.imu_cfg, 49)  # IMU disabled
        ctx.set(sub.baro_cfg, (1 << 9) | 0x100 | MIN_DIV)
        ctx.set(sub.baro.ready, 1)
        await ctx.tick().repeat(3 * 1000 + 3 * 1300 + 2000)
        got.append((ctx.get(sub.baro_samples), ctx.get(sub.baro_errors)))

    sim.add_testbench(pusher, background=True)
    sim.add_testbench(collect, background=True)
    sim.add_testbench(main)
    sim.run()
    p, t = B.compensate_fp32([s["up"] for s in samples], [s["ut"] for s in samples])
    assert got == [(int(a), int(b)) for a, b in zip(p, t, strict=True)] + [(3, 0)]


def _loopback_inputs(n, seed):
    s = _samples(n, seed)
    return {"up": np.array([x["up"] for x in s]), "ut": np.array([x["ut"] for x in s])}


def _loopback_model(seen):
    return {"up": seen["up"], "ut": seen["ut"]}


def test_loopback_amaranth_with_gaps():
    """Emulator -> pins -> SpiMasterBaro (INT mode, minimum divider) as a stream block through
    the verify harness: random input gaps; output order and values checked."""
    res = verify(Bmp390Loopback(MIN_DIV), _loopback_model, _loopback_inputs(16, seed=91),
                 valid_prob=0.3, seed=3)
    assert res.n_vectors == 16 and res.n_mismatches == 0, res


@pytest.mark.slow  # the emulators run in Verilator in every fpga-sim flight test too
def test_loopback_verilator(tmp_path):
    """The same loopback's emitted Verilog in Verilator: 100 samples (range corners + random)
    out of the master exactly as pushed in."""
    dut = Bmp390Loopback(MIN_DIV)
    assert (dut.LATENCY, 1 / dut.THROUGHPUT) == (INT_TO_SAMPLE_MIN, 624)
    res = verify(dut, _loopback_model, _loopback_inputs(100, seed=92),
                 backend="verilator", work_dir=tmp_path)
    assert res.n_vectors == 100 and res.n_mismatches == 0, res
    assert res.cycles >= 100 * read_cycles(MIN_DIV, SAMPLE_BYTES)
