"""Seed 001 serial TinyKalman (``tinykalman_serial_top``, navgate.systems.tinykalman.serial):
the bit-serial CORDIC and the serial data path (CORDIC + bit-serial filter) bit-exact against
the integer model (directed quadrants, +-180 deg, extremes, saturation, random vectors,
rejected samples; Amaranth and Verilator), the whole serial chip at pin level against the model
through the MPU-6500 device model (faults, latency, sample period, 10k samples and the x-io log
under -m slow), its SPI master's direct mode, UART and LFSR timer parameters, and its SG13G2
area."""

import gc
import os
import warnings
from pathlib import Path

import numpy as np
import pytest

from navgate.devices.mpu6500 import SPI_TIMING, WHO_AM_I_VALUE
from navgate.gateware import verify as V
from navgate.hw.asic import LIBERTY_NAME
from navgate.systems.tinykalman import model as tk
from navgate.systems.tinykalman import rtl_sim as R
from navgate.systems.tinykalman.rtl_sim import datapath_inputs, datapath_model, directed_angles
from navgate.systems.tinykalman.run import Words, model_stream, synthetic_motion, words_from_imu
from navgate.systems.tinykalman.serial import (
    SERIAL_CORDIC_LATENCY,
    SERIAL_DATAPATH_LATENCY,
    TinyKalmanSerialCordic,
    TinyKalmanSerialDatapath,
)
from navgate.systems.tinykalman.spi import Mpu6500Spi
from navgate.systems.tinykalman.top import (
    LFSR_TAPS,
    TinyKalmanTop,
    cordic_latency,
    datapath_latency,
    lfsr_timer,
    min_sample_period,
    timing,
)
from navgate.systems.tinykalman.uart import UartPacketTx

LOG = Path(os.environ.get("NAVGATE_SHARED_DATA",
                          Path(__file__).resolve().parents[4] / "shared" / "data")
           ) / "fusion_sensor_data.csv"

SERIAL_FAST = R.SimConfig(variant="serial")


def angles_model(s):
    roll, pitch, _, sat = tk.accel_angles(s["ax"], s["ay"], s["az"])
    return {"roll": roll, "pitch": pitch, "sat": sat.astype(np.int64)}


def wrap_cases():
    """Vectors at +-180 deg and the axes: ay = 0 with az < 0 (exactly 180 deg), ay = small
    beside it (the wrap), the four axes, the corners and the word extremes."""
    e = (-32768, -32767, -200, -3, -1, 0, 1, 2, 200, 32767)
    ay, az = np.meshgrid(e, e)
    ax = np.resize(np.array([-32768, 32767, 0, 1, -1, 12345]), ay.size)
    return {"ax": ax, "ay": ay.ravel(), "az": az.ravel()}


def test_serial_cordic_directed_quadrants_wrap_and_extremes():
    ins = directed_angles()
    w = wrap_cases()
    ins = {k: np.concatenate([ins[k], w[k]]) for k in ins}
    exp = angles_model(ins)
    assert {(np.sign(a), np.sign(b)) for a, b in zip(ins["az"], ins["ay"], strict=True)} >= {
        (1, 1), (1, -1), (-1, 1), (-1, -1)}
    assert exp["sat"].any() and not exp["sat"].all()
    assert (exp["roll"] == -32768).any(), "the set must hit exactly 180 deg"
    assert (exp["roll"] > 32000).any() and (exp["roll"] < -32000).any()
    res = V.verify(TinyKalmanSerialCordic(), angles_model, ins, valid_prob=0.6,
                   ready_prob=0.7, seed=3, backend="verilator")
    res.assert_ok()
    # 17 + 17 CORDIC passes and 3 passes for the pitch vector's y, 18 clocks each, + 1
    assert res.latency == TinyKalmanSerialCordic.LATENCY == SERIAL_CORDIC_LATENCY == 667


def test_serial_cordic_amaranth_random_stalls():
    """Amaranth's own simulator, random vectors and random valid/ready."""
    rng = np.random.default_rng(21)
    ins = {k: rng.integers(-32768, 32768, 40) for k in ("ax", "ay", "az")}
    res = V.verify(TinyKalmanSerialCordic(), angles_model, ins, valid_prob=0.5, ready_prob=0.5,
                   seed=4)
    res.assert_ok()
    assert res.latency == 667


@pytest.mark.parametrize("n", [300, pytest.param(20_000, marks=pytest.mark.slow)])
def test_serial_cordic_verilator_random_full_rate(n):
    rng = np.random.default_rng(11)
    ins = {k: rng.integers(-32768, 32768, n) for k in ("ax", "ay", "az")}
    res = V.verify(TinyKalmanSerialCordic(), angles_model, ins, backend="verilator")
    res.assert_ok()
    assert res.cycles == n * 668  # THROUGHPUT = 1/668


def serial_datapath_model(seen):
    exp = datapath_model(seen)
    return {k: exp[k] for k in ("roll", "pitch", "sat", "ok")}


def wrap_segment(n):
    """Samples whose filter state runs through +-180 deg: the measurement at 179 deg, the
    gyro at full scale (+511 LSB per sample), a rejected sample in the middle."""
    rr = np.radians(179.0)
    g = 16384
    seg = {"ax": np.full(n, -g // 3, np.int64),
           "ay": np.full(n, round(np.sin(rr) * g), np.int64),
           "az": np.full(n, round(np.cos(rr) * g), np.int64),
           "gx": np.full(n, 32767, np.int64), "gy": np.full(n, -32768, np.int64),
           "ok": np.ones(n, np.int64)}
    seg["ok"][n // 2] = 0
    return seg


def test_serial_datapath_verilator_random_with_rejected_samples():
    """The serial data path as a stream block (its own copies of ax, gy, ok): CORDIC, pitch
    vector and the bit-serial filter, with rejected samples (state held), the state wrapping
    through +-180 deg with full-scale rates, and random stalls."""
    w = synthetic_motion(300, seed=2)
    rng = np.random.default_rng(9)
    ok = (rng.random(300) > 0.1).astype(np.int64)
    ins = datapath_inputs(w, ok)
    seg = wrap_segment(100)
    ins = {k: np.concatenate([ins[k], seg[k]]) for k in ins}
    exp = serial_datapath_model(ins)
    assert exp["sat"].any() and not exp["ok"].all()
    jumps = np.abs(np.diff(exp["roll"][300:].astype(np.int64)))
    assert (jumps > 60000).any(), "the roll state must wrap through +-180 deg"
    dut = TinyKalmanSerialDatapath()
    res = V.verify(dut, serial_datapath_model, ins, backend="verilator", valid_prob=0.7,
                   ready_prob=0.6, seed=1)
    res.assert_ok()
    # CORDIC 667, then 2 x 16 clocks of prediction first and 2 x 2 x 16 of update
    assert res.latency == dut.LATENCY == 667 + 32 + 64 == 763


def test_serial_datapath_amaranth_extreme_rates():
    """Amaranth's simulator: full-scale rates of both signs (the sign extension of
    ``rate >>> 6``), a rejected sample, stalls."""
    seg = wrap_segment(6)
    seg["gx"][:] = [32767, -32768, -1, 64, -65, 32767]
    seg["gy"][:] = [-32768, 32767, 63, -64, 1, -32768]
    res = V.verify(TinyKalmanSerialDatapath(), serial_datapath_model, seg, valid_prob=0.8,
                   ready_prob=0.8, seed=2)
    res.assert_ok()


@pytest.mark.parametrize("make,match", [
    (lambda: TinyKalmanSerialCordic(spi_fed=True), "held_input"),
    (lambda: TinyKalmanSerialDatapath(held_input=False, spi_fed=True), "held_input"),
    (lambda: Mpu6500Spi(5, external=("ay",)), "direct"),
    (lambda: Mpu6500Spi(5, direct=True, external=("temp",)), "unknown word"),
    (lambda: UartPacketTx(0), "n_bytes"),
    (lambda: UartPacketTx(6, 0), "baud_div"),
    (lambda: TinyKalmanTop(2, 4, min_sample_period(2, 4, "serial") - 1, variant="serial"),
     "sample_period"),
    (lambda: TinyKalmanTop(1, 4, 100_000, variant="serial"), "spi_div"),
    (lambda: TinyKalmanTop(variant="bitwise"), "variant"),
])
def test_serial_parameters_checked(make, match):
    """A ValueError naming the parameter, raised before the component exists (no Amaranth
    "never used" warning: navgate.gateware.parameters)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(ValueError, match=match):
            make()
        gc.collect()
    assert not [w for w in caught if "never used" in str(w.message)]


def test_lfsr_timer_rejects_a_period_too_long():
    with pytest.raises(ValueError, match="longer than"):
        lfsr_timer(1 << 21)


def test_lfsr_taps_are_maximal_for_the_chip_periods():
    """The timer's LFSR from seed 1 reaches sample_period states without repeating (the
    function checks it) for the chip's 10 ms and the shortest FAST period; the 17-bit taps
    give the full 2^17 - 1 sequence."""
    assert lfsr_timer(100_000)[:3] == (17, LFSR_TAPS[17], 1)
    assert lfsr_timer((1 << 17) - 1)[0] == 17
    assert min_sample_period(2, 4, "serial") == 1535
    assert lfsr_timer(1535)[0] == 11 and lfsr_timer(1023)[0] == 10


def test_serial_timing_budget_and_parameters():
    """The serial chip at 10 MHz: latency CS_N rising -> first start bit, slack in 10 ms."""
    t = timing(variant="serial")
    # CS_N-high gap, SPI result, data path (the predictions ran during the burst), start bit
    assert t["latency_cs_rise_to_start_bit"] == 5 + 1 + 731 == 737
    assert datapath_latency("serial") == SERIAL_DATAPATH_LATENCY == 667 + 64
    assert t["slack_cycles"] == 100_000 - (1386 + 737 + 62520) == 35357
    assert t["baud"] == pytest.approx(9596.93, abs=0.01)
    assert cordic_latency("serial") == 667 and cordic_latency("parallel") == 37
    assert timing()["latency_cs_rise_to_start_bit"] == 45  # the parallel chip, unchanged
    with pytest.raises(ValueError, match="variant"):
        cordic_latency("bitwise")
    with pytest.raises(ValueError):
        TinyKalmanTop(2, 4, min_sample_period(2, 4, "serial") - 1, variant="serial")


def test_serial_chip_faults_and_latency_amaranth():
    """Stuck MISO, missing part, wrong part: the serial chip holds the filter, repeats the
    held angles and flags uio_out[0], like the parallel chip; latency 2 + 1 + 731 clocks;
    bursts exactly one sample period apart (the LFSR timer)."""
    w = synthetic_motion(7, seed=5)
    faults = {2: "stuck0", 3: "absent", 4: "who_am_i", 5: None}
    run = R.run_amaranth(w.bursts(), 7, SERIAL_FAST, faults=faults)
    exp, whos = R.expected_stream(run.device.log, 7)
    assert whos == [0x70, 0x70, 0x00, 0xFF, 0x71, 0x70, 0x70]
    assert run.uart == exp
    flags = run.extra["uio_out_at_packet_start"]
    assert [f & 1 for f in flags] == [0, 0, 1, 1, 1, 0, 0]
    assert run.latencies == [2 + 1 + 731] * 7
    rises = run.extra["cs_rises"]  # WHO_AM_I then burst, every sample
    assert len(rises) == 14
    assert set(np.diff(rises[::2])) == {SERIAL_FAST.period}


@pytest.mark.slow
def test_serial_chip_verilator_stream_with_faults():
    n = 60
    w = synthetic_motion(n, seed=7)
    faults = {20: "stuck0", 23: None, 40: "absent", 42: None, 50: "who_am_i", 51: "stuck1",
              52: None}
    run = R.run_verilator(w.bursts(), n, SERIAL_FAST, faults=faults)
    exp, whos = R.expected_stream(run.extra["log"], n)
    assert len(run.uart) == 6 * n and run.uart == exp
    assert [k for k, v in enumerate(whos) if v != WHO_AM_I_VALUE] == [20, 21, 22, 40, 41, 50, 51]
    assert set(run.latencies) == {2 + 1 + 731}
    assert run.uart[:6 * 20] == model_stream(Words(w.words[:20], 0))


def real_words(n=None):
    from navgate.sim.imu_log import read_imu_csv

    log = read_imu_csv(LOG)
    n = len(log) if n is None else n
    return words_from_imu(log.acc[:n], log.gyro[:n])


@pytest.mark.slow
def test_serial_chip_verilator_10k_synthetic():
    w = synthetic_motion(10_000, seed=2)
    run = R.run_verilator(w.bursts(), len(w), SERIAL_FAST)
    assert run.uart == model_stream(w)


@pytest.mark.slow
@pytest.mark.skipif(not LOG.exists(), reason="real log not present")
def test_serial_chip_verilator_real_log_all():
    w = real_words()
    run = R.run_verilator(w.bursts(), len(w), SERIAL_FAST)
    assert run.uart == model_stream(w)


@pytest.mark.slow
def test_serial_chip_verilator_real_dividers():
    """The serial chip as taped out: 1 MHz SCLK against the data sheet, 9596.9 baud, 10 ms."""
    cfg = R.SimConfig(spi_div=5, baud_div=1042, sample_period=100_000, variant="serial")
    w = synthetic_motion(3, seed=1)
    run = R.run_verilator(w.bursts(), 3, cfg, timing=SPI_TIMING)
    assert run.extra["violation_count"] == 0, run.extra["violations"]
    assert run.uart == model_stream(w)
    assert set(run.latencies) == {737}


# ------------------------------------------------------------------------------ SG13G2

LIBERTY = Path(__file__).resolve().parents[4] / "shared" / "asic" / LIBERTY_NAME


@pytest.mark.skipif(not LIBERTY.is_file(), reason="SG13G2 Liberty file absent")
def test_serial_chip_sg13g2_area_and_flip_flops(tmp_path):
    """Yosys 0.70 + the IHP SG13G2 typical Liberty (navgate.hw.asic): the serial chip's exact
    pre-layout area and flip-flops, and where they sit (docs/seed001-tinykalman.md)."""
    from navgate.hw.asic import synthesize_asic
    from navgate.hw.verilog import emit_verilog
    from navgate.systems.tinykalman.top import TinyKalmanSerialTop

    name = "tinykalman_serial_top"
    got = synthesize_asic(emit_verilog(TinyKalmanSerialTop(), name), name, tmp_path, LIBERTY)
    assert round(got["area_um2"], 1) == 17820.3
    assert got["flip_flops"] == 178 and got["latches"] == 0
    assert got["tile"] == "1x1" and got["tile_percent"]["1x1"] == 56.9
    ffs = got["flip_flops_by_register"]
    assert sum(ffs.values()) == 178
    # the bit-serial CORDIC: two 18-bit circulating registers that also take ay and az from
    # the SPI master; z takes the rates; no staging copies, no SPI assembly register
    assert ffs["core.datapath.x"] == ffs["core.datapath.y"] == 18
    assert ffs["core.datapath.z"] == 16 and ffs["core.datapath.ax_bits"] == 15
    assert ffs["core.timer"] == 17
    assert not any(k.endswith(("shift", "ax_neg", "gx_bits", "gy_bits")) for k in ffs)
    assert got["timing"]["longest_path_ns"] == pytest.approx(2.564, abs=1e-3)
