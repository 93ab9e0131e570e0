"""Seed 000 sensor interfaces in the Amaranth simulator against the bit-level device models:
sample streams delivered without loss, duplication or change; every fault class counted,
flagged, never delivered, with recovery on the next sample; the models' timing checks."""

import numpy as np
import pytest

from navgate.devices import adis16500 as A
from navgate.devices import bmp390 as B
from navgate.devices import tfluna as L
from navgate.systems.ins_trn.pl.sensors.sim_bench import run_baro, run_imu, run_lidar
from navgate.systems.ins_trn.pl.sensors.spi_master_imu import BURST_LATENCY

IMU_FAULTS = {3: "bad_checksum", 7: "stuck_low", 11: "stuck_high", 15: "missing"}


def _imu_stream(n, faults=None, seed=0):
    rng = np.random.default_rng(seed)
    return A.ImuStream(rng.integers(-32768, 32768, (n, 3)), rng.integers(-32768, 32768, (n, 3)),
                       temp=rng.integers(-400, 850, n), diag=np.zeros(n, int),
                       faults=faults or {})


def _imu_expected(st, indices):
    return [{"diag": 0, "gx": int(st.gyro[k, 0]), "gy": int(st.gyro[k, 1]),
             "gz": int(st.gyro[k, 2]), "ax": int(st.accel[k, 0]), "ay": int(st.accel[k, 1]),
             "az": int(st.accel[k, 2]), "temp": int(st.temp[k]), "cntr": k + 1}
            for k in indices]


def test_imu_stream_with_every_fault_class():
    st = _imu_stream(40, IMU_FAULTS)
    run = run_imu(st, 20)
    served = run.model.served
    assert len(served) >= 18 and served == list(range(len(served)))
    good = [k for k in served if k not in IMU_FAULTS]
    assert run.got == _imu_expected(st, good)  # nothing lost, duplicated, altered or faulty
    assert run.counters["error_count"] == len([k for k in served if k in IMU_FAULTS]) == 4
    assert run.counters["sample_count"] == len(good)
    assert run.flag_rises == 4  # flagged once per (isolated) fault ...
    assert run.counters["sensor_error"] == 0  # ... and cleared by the next good burst
    assert run.model.violations == []


def test_imu_default_configuration_at_100_mhz_meets_the_data_sheet():
    """cfg_spi_div = 49 (1 MHz burst clock) at 100 MHz, 200 us sample period (the burst takes
    182 us, so CS_N stays high 18 us >= tSTALL)."""
    st = _imu_stream(4)
    run = run_imu(st, 3, clk_hz=100e6, div=49, rate=200, tick_cycles=100)
    assert run.got == _imu_expected(st, [0, 1])
    assert run.model.violations == []
    assert run.first_valid_cycle - run.first_cs_cycle == BURST_LATENCY


def test_imu_wrong_master_configuration_is_reported_by_the_model():
    """2 MHz burst clock (div 2 at 12 MHz) and a sample period that leaves CS_N high 9 us."""
    st = _imu_stream(4)
    run = run_imu(st, 3, clk_hz=12e6, div=2, rate=1200)
    codes = {v.code for v in run.model.violations}
    assert {"f_sclk", "t_cs_high", "t_high", "t_low"} <= codes


def test_imu_fifo_full_counts_lost_samples():
    st = _imu_stream(24)
    run = run_imu(st, 20, ready=False)
    assert run.counters["sample_count"] == 16  # the FIFO depth
    assert run.counters["error_count"] == len(run.model.served) - 16 > 0


BARO_FAULTS = {-1: "missing", 2: "stuck_low", 4: "stuck_high", 6: "missing"}


def test_baro_nvm_and_stream_with_faults():
    rng = np.random.default_rng(2)
    n = 20
    st = B.BaroStream.from_physical(rng.uniform(*B.PRESSURE_RANGE_PA, n),
                                    rng.uniform(*B.TEMPERATURE_RANGE_C, n), faults=BARO_FAULTS)
    run = run_baro(st, 14)
    served = run.model.served
    assert len(served) >= 8 and served == list(range(len(served)))
    good = [k for k in served if k not in BARO_FAULTS]
    nvm = int.from_bytes(B.nvm_bytes(), "little")
    assert run.got == [{"up": int(st.uncomp_press[k]), "ut": int(st.uncomp_temp[k]),
                        "nvm": nvm} for k in good]
    assert run.counters["error_count"] == 1 + len([k for k in served if k in BARO_FAULTS])
    assert run.model.nvm_reads == 2  # the failed start-up read was retried once
    assert run.flag_rises == 4 and run.counters["sensor_error"] == 0
    assert [w for w in run.model.writes] == [(B.REG["PWR_CTRL"], B.PWR_CTRL_NORMAL)] * 2
    assert run.model.violations == []


def _lidar_frames(n, seed=0):
    rng = np.random.default_rng(seed)
    strength = rng.integers(100, 3000, n)
    strength[5], strength[6] = 50, 65535  # unreliable: delivered with reliable = 0
    return L.encode_frames(rng.uniform(0.2, 8.0, n), strength, rng.uniform(-20, 60, n))


def _lidar_expected(frames, indices):
    d = L.decode_frames(frames)
    return [{"dist": int(d["dist_raw"][k]), "strength": int(d["strength"][k]),
             "temp": int(frames[k, 6]) | (int(frames[k, 7]) << 8),
             "reliable": int(d["reliable"][k])} for k in indices]


LIDAR_FAULTS = {2: "bad_checksum", 4: "drop", 9: "truncate", 12: "noise", 15: "framing_error",
                18: "noise", 21: "truncate", 24: "bad_checksum", 27: "framing_error"}


def test_lidar_frames_with_every_fault_class():
    frames = _lidar_frames(30)
    st = L.LidarStream(frames, LIDAR_FAULTS, seed=5)
    run = run_lidar(st, timeout_bits=200, tail_s=1e-3)
    exp = st.expected()
    assert run.got == _lidar_expected(frames, exp)  # resynchronised within one frame
    c = run.counters
    lost = len(frames) - len(exp)
    assert c["frame_count"] == len(exp)
    assert c["framing_errors"] == 2
    assert c["checksum_errors"] >= 2  # the two bad checksums (+ windows over noise/truncation)
    assert c["unreliable_count"] == 2
    assert c["timeout_count"] == lost  # one frame period without a frame = one timeout
    assert c["timed_out"] == 0 and c["overrun_count"] == 0
    assert run.flag_rises >= lost  # sensor_error pulses and timeouts flag every lost frame


@pytest.mark.parametrize("baud_error", [-L.BAUD_TOLERANCE, L.BAUD_TOLERANCE])
def test_lidar_tolerates_baud_rate_error(baud_error):
    frames = _lidar_frames(8, seed=1)
    run = run_lidar(L.LidarStream(frames), baud_error=baud_error, div=0)
    assert run.got == _lidar_expected(frames, range(8))
