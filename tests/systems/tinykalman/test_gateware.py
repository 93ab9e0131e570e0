"""Seed 001 TinyKalman gateware in Amaranth's simulator: blocks bit-exact against the integer
model (directed edge cases and random/real data), and the whole chip at pin level against the
model through the MPU-6500 device model (timing, latency, faults)."""

import os
from pathlib import Path

import numpy as np
import pytest

from navgate.devices.mpu6500 import SPI_TIMING, WHO_AM_I_VALUE
from navgate.gateware import verify as V
from navgate.systems.tinykalman import model as tk
from navgate.systems.tinykalman import rtl_sim as R
from navgate.systems.tinykalman.datapath import KalmanSteady, TinyKalmanCordic, TinyKalmanDatapath
from navgate.systems.tinykalman.rtl_sim import datapath_inputs, datapath_model, directed_angles
from navgate.systems.tinykalman.run import model_stream, synthetic_motion, words_from_imu
from navgate.systems.tinykalman.spi import Mpu6500Spi, spi_cycles
from navgate.systems.tinykalman.top import TinyKalmanTop, min_sample_period, timing
from navgate.systems.tinykalman.uart import UartTx

# the real x-io log in ../shared/data beside the checkout (as tests/conftest.py finds it)
LOG = Path(os.environ.get("NAVGATE_SHARED_DATA",
                          Path(__file__).resolve().parents[4] / "shared" / "data")
           ) / "fusion_sensor_data.csv"


def angles_model(s):
    roll, pitch, mag, sat = tk.accel_angles(s["ax"], s["ay"], s["az"])
    return {"roll": roll, "pitch": pitch, "mag": mag, "sat": sat.astype(np.int64)}


def test_cordic_block_directed_quadrants_and_extremes():
    ins = directed_angles()
    exp = angles_model(ins)
    # the directed set covers every quadrant and the saturation
    assert {(np.sign(a), np.sign(b)) for a, b in zip(ins["az"], ins["ay"], strict=True)} >= {
        (1, 1), (1, -1), (-1, 1), (-1, -1)}
    assert exp["sat"].any() and not exp["sat"].all()
    res = V.verify(TinyKalmanCordic(), angles_model, ins, valid_prob=0.6, ready_prob=0.7,
                   seed=3)
    res.assert_ok()
    assert res.latency == TinyKalmanCordic.LATENCY


def test_cordic_block_random_full_rate():
    rng = np.random.default_rng(11)
    ins = {k: rng.integers(-32768, 32768, 150) for k in ("ax", "ay", "az")}
    res = V.verify(TinyKalmanCordic(), angles_model, ins)
    res.assert_ok()
    # THROUGHPUT = 1/38: 150 results in 150 * 38 cycles (+ the pipeline fill)
    assert res.cycles == 150 * 38


def test_kalman_block_wraps_at_180_deg():
    """The state runs up through +180 deg (rate pushes, measurement sits at -179 deg): the
    16-bit words wrap and the innovation takes the short way round, as the model."""
    n = 400
    ins = {"roll_m": np.full(n, -32600), "pitch_m": np.full(n, 32600),
           "gx": np.full(n, 32767), "gy": np.full(n, -32768), "use": np.ones(n, np.int64)}
    ins["use"][::7] = 0

    def model(s):
        roll, pitch, r, p = [], [], 0, 0
        for k in range(len(s["gx"])):
            if s["use"][k]:
                r = int(tk.kalman_step(r, s["gx"][k], s["roll_m"][k]))
                p = int(tk.kalman_step(p, s["gy"][k], s["pitch_m"][k]))
            roll.append(r)
            pitch.append(p)
        return {"roll": np.array(roll), "pitch": np.array(pitch)}

    exp = model(ins)
    jumps = np.abs(np.diff(exp["roll"]))
    assert (jumps > 60000).any(), "the sequence must cross +-180 deg"
    assert (np.abs(np.diff(exp["pitch"])) > 60000).any()
    res = V.verify(KalmanSteady(), model, ins, valid_prob=0.7, ready_prob=0.6, seed=5)
    res.assert_ok()
    assert res.latency == KalmanSteady.LATENCY


def test_datapath_synthetic_motion_with_rejected_samples():
    w = synthetic_motion(300, seed=2)
    ok = np.ones(300, np.int64)
    ok[50:60] = 0
    ins = datapath_inputs(w, ok)
    exp = datapath_model(ins)
    assert exp["sat"].any(), "synthetic motion must reach the mag_yz saturation"
    res = V.verify(TinyKalmanDatapath(), datapath_model, ins)
    res.assert_ok()
    assert res.latency == TinyKalmanDatapath.LATENCY


@pytest.mark.skipif(not LOG.exists(), reason="real log not present")
def test_datapath_real_log_head():
    from navgate.sim.imu_log import read_imu_csv

    log = read_imu_csv(LOG)
    w = words_from_imu(log.acc[:300], log.gyro[:300])
    V.verify(TinyKalmanDatapath(), datapath_model, datapath_inputs(w)).assert_ok()


# ------------------------------------------------------------------------------ chip


def test_parameters_checked():
    with pytest.raises(ValueError):
        Mpu6500Spi(spi_div=1)
    with pytest.raises(ValueError):
        UartTx(baud_div=0)
    with pytest.raises(ValueError):
        TinyKalmanTop(spi_div=2, baud_div=4, sample_period=min_sample_period(2, 4) - 1)


def test_default_timing_budget():
    """The real chip: 1 MHz SCLK, 9596.9 baud, 10 ms period (exact cycle figures)."""
    t = timing()
    assert t["sclk_hz"] == 1e6 and t["spi_cycles"] == spi_cycles(5) == 1391
    assert t["packet_cycles"] == 62520
    assert t["latency_cs_rise_to_start_bit"] == 45
    assert t["slack_cycles"] == 100_000 - (1386 + 45 + 62520) == 36049


def test_chip_real_spi_timing_and_latency():
    """SPI at the real divider (1 MHz) against the device's data-sheet limits; the latency
    from CS_N rising to the first start bit equals the documented figure."""
    cfg = R.SimConfig(spi_div=5, baud_div=4)
    w = synthetic_motion(3, seed=4)
    run = R.run_amaranth(w.bursts(), 3, cfg, timing=SPI_TIMING)
    assert run.device.violation_count == 0, run.device.stats.violations
    exp, whos = R.expected_stream(run.device.log, 3)
    assert run.uart == exp and whos == [WHO_AM_I_VALUE] * 3
    assert run.uart == model_stream(w)
    assert run.latencies == [timing(**cfg.params())["latency_cs_rise_to_start_bit"]] * 3 == [45] * 3
    assert run.framing_errors == 0


def test_chip_faults_keep_streaming_held_angles_and_flag():
    """Stuck MISO, missing part, wrong part: the filter holds, packets repeat the held angles,
    uio_out[0] is high for those samples; the stream recovers when the part does."""
    w = synthetic_motion(9, seed=5)
    faults = {2: "stuck0", 3: "absent", 4: "who_am_i", 5: "stuck1", 6: None}
    run = R.run_amaranth(w.bursts(), 9, R.FAST, faults=faults)
    exp, whos = R.expected_stream(run.device.log, 9)
    assert whos == [0x70, 0x70, 0x00, 0xFF, 0x71, 0xFF, 0x70, 0x70, 0x70]
    assert run.uart == exp
    pk = [run.uart[6 * k:6 * k + 6] for k in range(9)]
    assert pk[1] == pk[2] == pk[3] == pk[4] == pk[5] != pk[6]
    flags = run.extra["uio_out_at_packet_start"]
    assert [f & 1 for f in flags] == [0, 0, 1, 1, 1, 1, 0, 0, 0]
    assert run.latencies == [42] * 9
