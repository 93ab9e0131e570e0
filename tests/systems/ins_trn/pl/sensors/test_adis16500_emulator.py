"""ADIS16500 emulator (gateware SPI slave) against SpiMasterImu in the Amaranth simulator:
pins only between the two (asynchronous-style: synchronisers on both sides), data-ready and
timer modes, the master's minimum and default dividers; every sample pushed into the emulator
comes out of the master's FIFO unchanged, once, in order, with DATA_CNTR counting; underruns
are all-zero bursts that the master counts as errors."""

import numpy as np
import pytest
from amaranth.hdl import Elaboratable, Module
from amaranth.sim import Simulator

from navgate.devices import adis16500 as A
from navgate.gateware.verify import verify
from navgate.systems.ins_trn.pl.sensors.adis16500_emulator import (
    MIN_HALF,
    Adis16500Emulator,
    Adis16500Loopback,
)
from navgate.systems.ins_trn.pl.sensors.sensor_subsystem import IMU_LAYOUT, SensorSubsystem
from navgate.systems.ins_trn.pl.sensors.sim_bench import run_emulator_transactions, run_imu_emulated
from navgate.systems.ins_trn.pl.sensors.spi_master_imu import (
    BURST_LATENCY,
    burst_cycles,
)

FIELDS = ("gx", "gy", "gz", "ax", "ay", "az", "temp", "diag")
MIN_DIV = MIN_HALF - 1  # cfg_spi_div 2: SCLK half period 3 cycles


def _samples(n, seed):
    """n samples: extreme words first (-32768, 32767, 0, mixed), then seeded random words."""
    rng = np.random.default_rng(seed)
    fixed = [[-32768] * 7 + [0xFFFF], [32767] * 7 + [0x7FFF], [0] * 8,
             [-32768, 32767, 0, -1, 1, -32768, 32767, 0x8000]]
    out = [dict(zip(FIELDS, v, strict=True)) for v in fixed]
    for _ in range(n - len(fixed)):
        v = [int(x) for x in rng.integers(-32768, 32768, 7)] + [int(rng.integers(0, 1 << 16))]
        out.append(dict(zip(FIELDS, v, strict=True)))
    return out[:n]


def _expected(samples, first_cntr=1):
    return [s | {"cntr": (first_cntr + k) & 0xFFFF} for k, s in enumerate(samples)]


#: one burst in DR mode at the minimum divider: CS_N falling -> sample at the FIFO output
DR_LATENCY_MIN = burst_cycles(MIN_DIV) + 2
#: DR mode, samples waiting: CS_N falling to the next CS_N falling: the burst (CS_N low) plus
#: the DR round trip: emulator CS_N synchroniser + edge (3), DR register (1), master DR
#: synchroniser + edge (3), the FSM's IDLE -> CS_N low (1)
DR_PERIOD_MIN = burst_cycles(MIN_DIV) + 8
assert (DR_LATENCY_MIN, DR_PERIOD_MIN) == (1094, 1100)  # the figures in the docs


def test_dr_mode_minimum_divider_random_samples():
    """40 samples at SCLK half period 3: pushed with random gaps, some in quick succession
    (the emulator FIFO holds up to 4 while a burst runs): every sample delivered once, in
    order, unchanged, DATA_CNTR 1..40; no underruns, no master errors; the exact cycles."""
    n = 40
    samples = _samples(n, seed=11)
    rng = np.random.default_rng(12)
    gaps = [int(g) for g in rng.choice([1, 3, 400, 1500, 2500], n)]
    res = run_imu_emulated(samples, div=MIN_DIV, dr_sync=1, cycles=sum(gaps) + n * 1200 + 2000,
                           gaps=gaps)
    assert res["got"] == _expected(samples)
    assert res["bursts"] == n and res["underruns"] == 0 and res["dropped"] == 0
    assert res["sample_count"] == n and res["error_count"] == 0 and res["sensor_error"] == 0
    # one CS_N falling per sample: DR mode never reads a sample twice or skips one
    assert len(res["cs_fall_at"]) == n
    lat = [v - c for c, v in zip(res["cs_fall_at"], res["valid_at"], strict=True)]
    assert lat == [DR_LATENCY_MIN] * n
    periods = np.diff(res["cs_fall_at"])
    assert periods.min() == DR_PERIOD_MIN  # back to back while samples were waiting
    assert np.count_nonzero(periods == DR_PERIOD_MIN) >= 5


def test_dr_mode_default_divider():
    """cfg_spi_div 49 (the 100 MHz default, 1 MHz SCLK): three samples, the master's
    documented BURST_LATENCY from CS_N falling to the sample."""
    samples = _samples(3, seed=5)
    res = run_imu_emulated(samples, div=49, dr_sync=1, cycles=3 * 18300 + 200)
    assert res["got"] == _expected(samples)
    assert res["bursts"] == 3 and res["error_count"] == 0
    lat = [v - c for c, v in zip(res["cs_fall_at"], res["valid_at"], strict=True)]
    assert lat == [BURST_LATENCY] * 3
    assert list(np.diff(res["cs_fall_at"])) == [burst_cycles(49) + 8] * 2  # back to back


@pytest.mark.parametrize("div", [MIN_DIV, pytest.param(49, marks=pytest.mark.slow)])
def test_timer_mode_with_underruns(div):
    """Timer mode (cfg_dr_sync 0, DR ignored): samples waiting -> delivered in order; then
    the emulator runs dry -> all-zero bursts, counted by both sides, flagged, never
    delivered; DATA_CNTR does not advance on them; then delivery resumes."""
    burst = burst_cycles(div)
    rate = burst + 300
    first = _samples(6, seed=7 + div)
    second = _samples(6, seed=100 + div)
    # 4 of the first fill the emulator FIFO before the first timer burst (at `rate`), the
    # other 2 follow as bursts pop; bursts 7 and 8 underrun; the second batch arrives just
    # before burst 9 and bursts 9..13 serve 5 of it
    res = run_imu_emulated(first, div=div, dr_sync=0, rate=rate, cycles=13 * rate + burst + 50,
               push_after=(9 * rate - 50, second))
    assert len(res["cs_fall_at"]) == 13
    assert res["got"] == _expected(first) + _expected(second[:5], first_cntr=7)
    assert (res["bursts"], res["underruns"], res["dropped"]) == (11, 2, 0)
    assert res["error_count"] == 2 and res["sample_count"] == 11
    assert res["sensor_error"] == 0  # cleared by the next good burst


def test_dr_mode_switched_on_while_samples_wait():
    """Samples queued in the emulator (DR high) before IMU_CFG.dr_sync is set, the timer too
    slow to fire: setting dr_sync starts a burst (the gated DR edge), and the bursts then
    drain the queue; before it, nothing is read."""
    samples = _samples(4, seed=6)
    res = run_imu_emulated(samples, div=MIN_DIV, dr_sync=1, rate=60000, dr_sync_at=3000,
                           cycles=3000 + 4 * DR_PERIOD_MIN + 50)
    assert res["cs_fall_at"][0] > 3000
    assert res["got"] == _expected(samples) and res["error_count"] == 0


def test_dr_mode_ignores_timer_and_timer_mode_ignores_dr():
    """DR mode with a fast timer: bursts only when samples are pushed (no underruns);
    timer mode with samples always waiting (DR high): one burst per timer period only."""
    samples = _samples(2, seed=3)
    res = run_imu_emulated(samples, div=MIN_DIV, dr_sync=1, rate=200, cycles=6000, gaps=[1, 3000])
    assert len(res["cs_fall_at"]) == 2 and res["underruns"] == 0
    assert res["got"] == _expected(samples)
    res = run_imu_emulated(_samples(4, seed=4), div=MIN_DIV, dr_sync=0, rate=1500,
                           cycles=4 * 1500 - 10)
    assert len(res["cs_fall_at"]) == 3  # at 1500, 3000, 4500 (not at DR)
    assert res["got"] == _expected(_samples(4, seed=4))[:3]


def _phyrun_imu_emulated(push, transactions):
    """Push samples, then run transactions (lists of words sent, CS_N low around each);
    returns the words read, DR before/during/after each, and the emulator's counters."""
    out = run_emulator_transactions(Adis16500Emulator(), 16, push, transactions, ready="dr",
                                    counters=("bursts", "underruns", "dropped"))
    out["dr"] = out.pop("ready")
    return out


def test_burst_words_equal_the_device_encoder():
    """At the bit level (a bare SPI PHY at the minimum half period): the ten words after
    0x6800 are navgate.devices.adis16500.burst_words() of the sample with DATA_CNTR 1, 2
    (checksum included); the third burst underruns: ten zero words; DR low during each
    transaction and high after it only while samples are waiting."""
    samples = _samples(2, seed=31)
    burst = [A.BURST_CMD] + [0] * A.BURST_WORDS
    out = _phyrun_imu_emulated(samples, [burst, burst, burst])
    for k, s in enumerate(samples):
        want = A.burst_words([s["gx"], s["gy"], s["gz"]], [s["ax"], s["ay"], s["az"]],
                             s["temp"], s["diag"], k + 1)
        assert out["words"][k] == [0] + [int(w) for w in want]
    assert out["words"][2] == [0] * 11
    assert out["dr"] == [[1, 0, 1], [1, 0, 0], [0, 0, 0]]
    assert (out["bursts"], out["underruns"], out["dropped"]) == (2, 1, 0)


def test_other_commands_drop_the_sample():
    """A transaction whose command is not 0x6800 (a PROD_ID read) reads zeros and drops the
    sample popped at CS_N falling; the next burst serves the next sample with DATA_CNTR 1."""
    samples = _samples(2, seed=32)
    out = _phyrun_imu_emulated(samples, [[A.REG["PROD_ID"] << 8, 0, 0], [A.BURST_CMD] + [0] * 10])
    assert out["words"][0] == [0, 0, 0]
    s = samples[1]
    want = A.burst_words([s["gx"], s["gy"], s["gz"]], [s["ax"], s["ay"], s["az"]],
                         s["temp"], s["diag"], 1)
    assert out["words"][1] == [0] + [int(w) for w in want]
    assert (out["bursts"], out["underruns"], out["dropped"]) == (1, 0, 1)


def test_sensor_subsystem_raw_words_end_to_end():
    """SensorSubsystem(calibrate=False) with the emulator on its IMU pins in DR mode
    (IMU_CFG = dr_sync | enable | div 2): the imu stream carries the int16 words sign-extended
    to 32 bits, DATA_CNTR and DIAG_STAT; no calibration ports."""
    samples = _samples(8, seed=21)

    class Top(Elaboratable):
        def __init__(self):
            self.emu = Adis16500Emulator()
            self.sub = SensorSubsystem(tick_cycles=1, calibrate=False)

        def elaborate(self, platform):
            m = Module()
            m.submodules.emu, m.submodules.sub = emu, sub = self.emu, self.sub
            m.d.comb += [emu.sclk.eq(sub.imu_sclk), emu.mosi.eq(sub.imu_mosi),
                         emu.cs_n.eq(sub.imu_cs_n), sub.imu_miso.eq(emu.miso),
                         sub.imu_dr.eq(emu.dr)]
            return m

    top = Top()
    sub, emu = top.sub, top.emu
    assert not hasattr(sub, "cal_we") and sub.LATENCY == BURST_LATENCY
    sim = Simulator(top)
    sim.add_clock(1e-8)
    got = []

    async def pusher(ctx):
        for s in samples:
            ctx.set(emu.samples.payload, s)
            ctx.set(emu.samples.valid, 1)
            await ctx.tick().until(emu.samples.ready)
        ctx.set(emu.samples.valid, 0)

    async def collect(ctx):
        async for (_v,) in ctx.posedge(sub.imu.valid):
            got.append({n: ctx.get(getattr(sub.imu.payload, n)) for n in IMU_LAYOUT.members})

    async def main(ctx):
        ctx.set(sub.imu_cfg, (1 << 9) | 0x100 | MIN_DIV)
        ctx.set(sub.update_rate, 100)  # a timer this fast would underrun: DR mode ignores it
        ctx.set(sub.imu.ready, 1)
        await ctx.tick().repeat(8 * (DR_PERIOD_MIN + 10))
        got.append({"errors": ctx.get(sub.imu_errors), "n": ctx.get(sub.imu_samples)})

    sim.add_testbench(pusher, background=True)
    sim.add_testbench(collect, background=True)
    sim.add_testbench(main)
    sim.run()

    def s32(v):
        return v & 0xFFFFFFFF

    exp = [{n: s32(s[n]) for n in ("gx", "gy", "gz", "ax", "ay", "az")}
           | {"cntr": k + 1, "diag": s["diag"]} for k, s in enumerate(samples)]
    assert got == exp + [{"errors": 0, "n": 8}]
    assert exp[0]["gx"] == 0xFFFF8000 and exp[1]["gx"] == 0x7FFF  # sign extension checked


def _loopback_model(seen):
    n = len(seen["gx"])
    return {f: seen[f] for f in FIELDS} | {"cntr": (np.arange(n) + 1) & 0xFFFF}


def _loopback_inputs(n, seed):
    s = _samples(n, seed)
    return {f: np.array([x[f] for x in s]) for f in FIELDS}


def test_loopback_amaranth_with_gaps_and_stalls():
    """The same loopback through the verify harness in Amaranth: random input gaps and
    output stalls (the master's 16-deep FIFO absorbs them)."""
    res = verify(Adis16500Loopback(MIN_DIV), _loopback_model, _loopback_inputs(24, seed=41),
                 valid_prob=0.3, ready_prob=0.5, seed=2)
    assert res.n_vectors == 24 and res.n_mismatches == 0, res


@pytest.mark.slow  # the emulators run in Verilator in every fpga-sim flight test too
def test_loopback_verilator(tmp_path):
    """Emitted Verilog of emulator + master (DR mode, minimum divider) in Verilator: 200
    samples (extremes + random) out of the master exactly as pushed in, DATA_CNTR 1..200."""
    dut = Adis16500Loopback(MIN_DIV)
    assert (dut.LATENCY, 1 / dut.THROUGHPUT) == (DR_LATENCY_MIN, DR_PERIOD_MIN)
    res = verify(dut, _loopback_model, _loopback_inputs(200, seed=42),
                 backend="verilator", work_dir=tmp_path)
    assert res.n_vectors == 200 and res.n_mismatches == 0, res
    assert res.cycles >= 200 * DR_PERIOD_MIN
