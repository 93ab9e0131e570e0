"""Seed 001 TinyKalman in Verilator: the emitted Verilog of the whole chip at pin level (MPU-6500
device model on the SPI pins, cocotbext-uart on TX), and the data path block through the shared
stream harness, bit-exact against the integer model. Long runs (>= 10,000 samples of the real
log and of synthetic motion, the real-divider chip) are marked slow."""

import os
from pathlib import Path

import numpy as np
import pytest

from navgate.devices.mpu6500 import SPI_TIMING
from navgate.gateware import verify as V
from navgate.systems.tinykalman import rtl_sim as R
from navgate.systems.tinykalman.datapath import TinyKalmanDatapath
from navgate.systems.tinykalman.rtl_sim import datapath_inputs, datapath_model, directed_angles
from navgate.systems.tinykalman.run import Words, model_stream, synthetic_motion, words_from_imu

# the real x-io log in ../shared/data beside the checkout (as tests/conftest.py finds it)
LOG = Path(os.environ.get("NAVGATE_SHARED_DATA",
                          Path(__file__).resolve().parents[4] / "shared" / "data")
           ) / "fusion_sensor_data.csv"


def real_words(n=None):
    from navgate.sim.imu_log import read_imu_csv

    log = read_imu_csv(LOG)
    n = len(log) if n is None else n
    return words_from_imu(log.acc[:n], log.gyro[:n])


def test_chip_verilator_stream_with_faults():
    """100 sample periods, four kinds of fault in between: the bytes cocotbext-uart decodes
    equal the model's encoder on what the chip read; fault samples repeat the held angles."""
    n = 100
    w = synthetic_motion(n, seed=7)
    faults = {30: "stuck0", 33: None, 60: "absent", 62: None, 90: "who_am_i", 91: "stuck1",
              92: None}
    run = R.run_verilator(w.bursts(), n, R.FAST, faults=faults)
    exp, whos = R.expected_stream(run.extra["log"], n)
    assert len(run.uart) == 6 * n
    assert run.uart == exp
    bad = [k for k, v in enumerate(whos) if v != 0x70]
    assert bad == [30, 31, 32, 60, 61, 90, 91]
    assert run.uart[6 * 29:6 * 30] == run.uart[6 * 32:6 * 33]  # held through the fault
    assert set(run.latencies) == {R.FAST.spi_div + 40}
    # before the first fault the stream is the model's on the words served
    assert run.uart[:6 * 30] == model_stream(Words(w.words[:30], 0))


def test_datapath_verilator_directed_and_random():
    ang = directed_angles()
    m = len(ang["ax"])
    rng = np.random.default_rng(9)
    ins = {**ang, "gx": rng.integers(-32768, 32768, m), "gy": rng.integers(-32768, 32768, m),
           "ok": (rng.random(m) > 0.05).astype(np.int64)}
    res = V.verify(TinyKalmanDatapath(), datapath_model, ins, backend="verilator")
    res.assert_ok()


@pytest.mark.skipif(not LOG.exists(), reason="real log not present")
def test_datapath_verilator_real_log_head():
    w = real_words(300)
    V.verify(TinyKalmanDatapath(), datapath_model, datapath_inputs(w),
             backend="verilator").assert_ok()


# ------------------------------------------------------------------------------ slow


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["amaranth", "verilator"])
def test_datapath_10k_synthetic(backend):
    w = synthetic_motion(10_000, seed=2)
    res = V.verify(TinyKalmanDatapath(), datapath_model, datapath_inputs(w), backend=backend)
    res.assert_ok()
    assert res.n_vectors == 10_000


@pytest.mark.slow
@pytest.mark.skipif(not LOG.exists(), reason="real log not present")
@pytest.mark.parametrize("backend", ["amaranth", "verilator"])
def test_datapath_real_log_all(backend):
    w = real_words()
    assert len(w) >= 10_000
    res = V.verify(TinyKalmanDatapath(), datapath_model, datapath_inputs(w), backend=backend)
    res.assert_ok()


@pytest.mark.slow
def test_chip_verilator_10k_synthetic():
    w = synthetic_motion(10_000, seed=2)
    run = R.run_verilator(w.bursts(), len(w), R.FAST)
    assert run.uart == model_stream(w)


@pytest.mark.slow
@pytest.mark.skipif(not LOG.exists(), reason="real log not present")
def test_chip_verilator_real_log_all():
    w = real_words()
    run = R.run_verilator(w.bursts(), len(w), R.FAST)
    assert run.uart == model_stream(w)


@pytest.mark.slow
def test_chip_verilator_real_dividers():
    """The chip as taped out: 1 MHz SCLK checked against the data sheet, 9596.9 baud decoded
    by cocotbext-uart, 10 ms period; 3 samples (300,000 clocks)."""
    cfg = R.SimConfig(spi_div=5, baud_div=1042, sample_period=100_000)
    w = synthetic_motion(3, seed=1)
    run = R.run_verilator(w.bursts(), 3, cfg, timing=SPI_TIMING)
    assert run.extra["violation_count"] == 0, run.extra["violations"]
    assert run.uart == model_stream(w)
    assert set(run.latencies) == {45}
