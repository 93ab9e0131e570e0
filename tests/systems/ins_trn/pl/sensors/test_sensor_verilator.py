"""Sensor interfaces' emitted Verilog in Verilator (cocotb) with the bit-level device models:
short streams with every fault class by default, >= 4,000-sample streams under ``slow``."""

import numpy as np
import pytest

from navgate.devices import adis16500 as A
from navgate.devices import bmp390 as B
from navgate.devices import tfluna as L
from navgate.systems.ins_trn.pl.sensors.verilator_bench import (
    long_streams,
    score_baro,
    score_imu,
    score_lidar,
    verilator_baro,
    verilator_imu,
    verilator_lidar,
)


def test_imu_verilator_with_faults(tmp_path):
    rng = np.random.default_rng(1)
    faults = {2: "bad_checksum", 5: "stuck_low", 8: "stuck_high", 11: "missing"}
    st = A.ImuStream(rng.integers(-32768, 32768, (30, 3)), rng.integers(-32768, 32768, (30, 3)),
                     temp=rng.integers(-400, 850, 30), faults=faults)
    s = score_imu(st, verilator_imu(st, 16, work_dir=tmp_path))
    assert s["served"] >= 14 and s["faults_served"] == 4 == s["errors_counted"]
    assert s["delivered"] == s["served"] - 4
    assert (s["lost"], s["duplicated"], s["altered_or_faulty_delivered"], s["violations"]) \
        == (0, 0, 0, 0) and s["in_order"]


def test_baro_verilator_with_faults(tmp_path):
    rng = np.random.default_rng(2)
    faults = {-1: "stuck_low", 2: "stuck_high", 4: "missing", 5: "stuck_low"}
    st = B.BaroStream.from_physical(rng.uniform(*B.PRESSURE_RANGE_PA, 30),
                                    rng.uniform(*B.TEMPERATURE_RANGE_C, 30), faults=faults)
    s = score_baro(st, verilator_baro(st, 15, work_dir=tmp_path))
    assert s["served"] >= 8 and s["faults_served"] == 3 and s["errors_counted"] == 4
    assert (s["lost"], s["duplicated_or_altered"], s["violations"]) == (0, 0, 0)


def test_lidar_verilator_with_faults_and_cocotbext_source(tmp_path):
    rng = np.random.default_rng(3)
    frames = L.encode_frames(rng.uniform(0.2, 8, 24), rng.integers(0, 3000, 24), 20.0)
    faults = {2: "bad_checksum", 5: "drop", 8: "truncate", 11: "noise", 14: "framing_error",
              17: "noise"}
    st = L.LidarStream(frames, faults, seed=4)
    s = score_lidar(st, verilator_lidar(frames, faults, div=1, seed=4, timeout_bits=200,
                                        work_dir=tmp_path / "a"))
    assert s["delivered"] == s["expected"] == 20 and s["lost"] == 0
    assert s["duplicated_or_altered"] == 0 and s["framing_errors"] == 1
    assert s["checksum_errors"] >= 1 and s["timeout_count"] == 4
    # an independent UART model (cocotbext-uart) sends the same frames cleanly
    s = score_lidar(L.LidarStream(frames), verilator_lidar(
        frames, None, source="cocotbext", div=1, frame_period_s=150 / L.BAUD,
        work_dir=tmp_path / "b"))
    assert s["delivered"] == 24 and s["lost"] == s["duplicated_or_altered"] == 0


@pytest.mark.slow
def test_long_streams_4000_samples(tmp_path):
    res = long_streams(4000, work_root=tmp_path)
    for name in ("imu", "baro"):
        s = res[name]
        assert s["served"] - s["faults_served"] >= 4000 - 1
        assert s["delivered"] == s["served"] - s["faults_served"]
        assert s["lost"] == 0 and s["violations"] == 0
    assert res["imu"]["duplicated"] == res["imu"]["altered_or_faulty_delivered"] == 0
    assert res["imu"]["errors_counted"] == res["imu"]["faults_served"]
    assert res["baro"]["duplicated_or_altered"] == 0
    assert res["baro"]["errors_counted"] == res["baro"]["faults_served"] + 1  # start-up
    for name in ("lidar", "lidar_cocotbext"):
        s = res[name]
        assert s["delivered"] == s["expected"] >= 4000 - 41 and s["lost"] == 0
        assert s["duplicated_or_altered"] == 0
