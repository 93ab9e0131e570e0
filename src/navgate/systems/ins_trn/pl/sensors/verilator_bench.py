"""Runs the sensor interfaces' emitted Verilog in Verilator under cocotb with the device models
(:mod:`.cocotb_bench`), through the build cache of :mod:`navgate.gateware.verify`."""

from __future__ import annotations

import json
import math
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from navgate.devices import tfluna
from navgate.gateware import verify as _verify

from .spi_master_baro import SpiMasterBaro
from .spi_master_imu import SAMPLE_LAYOUT, SpiMasterImu
from .uart_rx_lidar import FRAME_LAYOUT, UartRxLidar


def _layout(layout):
    out = []
    for name, f in layout:
        shape = f.shape
        out.append((name, shape.width, shape.signed))
    return out


def _run(component, top, testcase, job, work_dir):
    text = _verify.emit_verilog(component, top)
    build_dir = _verify._build_model(text, top)
    work = Path(work_dir or tempfile.mkdtemp(prefix=f"navgate-{top}-"))
    work.mkdir(parents=True, exist_ok=True)
    job_path = work / "job.json"
    job_path.write_text(json.dumps(job))
    from cocotb_tools.runner import get_runner

    with _verify._verilator_path():
        runner = get_runner("verilator")
        try:
            runner.test(test_module="navgate.systems.ins_trn.pl.sensors.cocotb_bench",
                        testcase=testcase, hdl_toplevel=top, hdl_toplevel_lang="verilog",
                        build_dir=build_dir, test_dir=work,
                        extra_env={"NAVGATE_SENSOR_JOB": str(job_path)},
                        results_xml=str(work / "results.xml"), log_file=work / "sim.log")
        except (SystemExit, subprocess.CalledProcessError) as exc:
            log = (work / "sim.log").read_text()[-4000:] if (work / "sim.log").exists() else ""
            raise _verify.VerifyError(f"cocotb run of {top} failed ({exc}):\n{log}") from None
    res = work / "result.json"
    if not res.exists():
        log = (work / "sim.log").read_text()[-4000:]
        raise _verify.VerifyError(f"cocotb run of {top} wrote no result:\n{log}")
    return json.loads(res.read_text())


def verilator_imu(stream, periods, *, clk_hz=6e6, div=2, rate=1300, work_dir=None):
    job = {"gyro": stream.gyro.tolist(), "accel": stream.accel.tolist(),
           "temp": stream.temp.tolist(), "faults": {str(k): v for k, v in stream.faults.items()},
           "period_ps": 2 * math.ceil(0.5e12 / clk_hz), "div": div, "rate": rate,
           "cycles": periods * rate, "layout": _layout(SAMPLE_LAYOUT)}
    return _run(SpiMasterImu(tick_cycles=1), "spi_master_imu", "imu_stream", job, work_dir)


def verilator_baro(stream, periods, *, clk_hz=30e6, div=2, rate=700, work_dir=None):
    from .baro_compensation import IN_LAYOUT

    job = {"up": np.asarray(stream.uncomp_press).tolist(),
           "ut": np.asarray(stream.uncomp_temp).tolist(),
           "faults": {str(k): v for k, v in stream.faults.items()},
           "period_ps": 2 * math.ceil(0.5e12 / clk_hz), "div": div, "rate": rate,
           "cycles": periods * rate + (div + 1) * 17 * 80, "layout": _layout(IN_LAYOUT)}
    return _run(SpiMasterBaro(tick_cycles=1), "spi_master_baro", "baro_stream", job, work_dir)


def verilator_lidar(frames, faults=None, *, source="navgate", div=2, seed=0,
                    frame_period_s=None, tail_s=1e-3, timeout_bits=2304, work_dir=None):
    clk_hz = tfluna.BAUD * 16 * (div + 1)
    char = 10 / tfluna.BAUD
    job = {"frames": np.asarray(frames).tolist(),
           "faults": {str(k): v for k, v in (faults or {}).items()}, "seed": seed,
           "source": source, "div": div, "period_ps": 2 * math.ceil(0.5e12 / clk_hz),
           "frame_period_s": frame_period_s or 15 * char, "tail_s": tail_s,
           "layout": _layout(FRAME_LAYOUT)}
    return _run(UartRxLidar(timeout_bits=timeout_bits), "uart_rx_lidar", "lidar_stream", job,
                work_dir)


# ---- stream scoring (shared by the tests and benchmarks/bench_sensors.py) ------------------

def score_imu(stream, result) -> dict:
    """Compare delivered IMU samples with the served ones: lost / duplicated / altered counts.
    A served sample with a fault must not be delivered and must be counted as an error."""
    served = result["served"]
    faulty = [k for k in served if k in stream.faults]
    good = [k for k in served if k not in stream.faults]
    exp = {k + 1: k for k in good}  # DATA_CNTR -> sample index
    seen = [g["cntr"] for g in result["got"]]
    altered = 0
    for g in result["got"]:
        k = exp.get(g["cntr"])
        if k is None:
            altered += 1
            continue
        want = ([int(x) for x in stream.gyro[k]] + [int(x) for x in stream.accel[k]]
                + [int(stream.temp[k])])
        have = [g[n] for n in ("gx", "gy", "gz", "ax", "ay", "az", "temp")]
        altered += want != have
    return {"served": len(served), "delivered": len(seen), "faults_served": len(faulty),
            "errors_counted": result["error_count"],
            "lost": len(set(exp) - set(seen)), "duplicated": len(seen) - len(set(seen)),
            "altered_or_faulty_delivered": altered, "violations": len(result["violations"]),
            "in_order": seen == sorted(seen)}


def score_baro(stream, result) -> dict:
    served = result["served"]
    faulty = [k for k in served if k in stream.faults]
    good = [k for k in served if k not in stream.faults]
    want = [(int(stream.uncomp_press[k]), int(stream.uncomp_temp[k])) for k in good]
    have = [(g["up"], g["ut"]) for g in result["got"]]
    # the stream is served in order, so a plain sequence comparison finds every difference
    import difflib

    sm = difflib.SequenceMatcher(a=want, b=have, autojunk=False)
    matched = sum(b.size for b in sm.get_matching_blocks())
    return {"served": len(served), "delivered": len(have), "faults_served": len(faulty),
            "errors_counted": result["error_count"], "lost": len(want) - matched,
            "duplicated_or_altered": len(have) - matched,
            "violations": len(result["violations"])}


def score_lidar(stream, result) -> dict:
    exp = stream.expected()
    f = stream.frames.astype(int)
    want = [(int(f[k, 2] | (f[k, 3] << 8)), int(f[k, 4] | (f[k, 5] << 8))) for k in exp]
    have = [(g["dist"], g["strength"]) for g in result["got"]]
    import difflib

    sm = difflib.SequenceMatcher(a=want, b=have, autojunk=False)
    matched = sum(b.size for b in sm.get_matching_blocks())
    return {"frames": len(f), "expected": len(want), "delivered": len(have),
            "lost": len(want) - matched, "duplicated_or_altered": len(have) - matched,
            **{k: result[k] for k in ("checksum_errors", "framing_errors", "timeout_count",
                                      "unreliable_count")}}


STREAMS = ("imu", "baro", "lidar", "lidar_cocotbext")


def long_streams(n: int = 4000, seed: int = 0, fault_every: int = 97, work_root=None,
                 only=STREAMS) -> dict:
    """The n-sample streams of each interface through Verilator, with faults of every class
    every ``fault_every`` samples (``lidar_cocotbext``: a clean stream from cocotbext-uart);
    returns the scores (benchmarks/bench_sensors.py and the slow tests)."""
    from navgate.devices import adis16500, bmp390

    root = Path(work_root) if work_root else None
    out = {}

    def wd(name):
        return None if root is None else root / name

    rng = np.random.default_rng(seed)
    if "imu" in only:
        faults = {k: adis16500.FAULTS[(k // fault_every) % 4]
                  for k in range(fault_every, n, fault_every)}
        m = n + len(faults) + 8
        imu = adis16500.ImuStream(rng.integers(-32768, 32768, (m, 3)),
                                  rng.integers(-32768, 32768, (m, 3)),
                                  temp=rng.integers(-400, 850, m), faults=faults)
        out["imu"] = score_imu(imu, verilator_imu(imu, n + len(faults) + 2,
                                                  work_dir=wd("imu")))
    rng = np.random.default_rng(seed + 1)
    if "baro" in only:
        faults = {k: bmp390.FAULTS[(k // fault_every) % 3]
                  for k in range(fault_every, n, fault_every)}
        faults[-1] = "missing"
        m = n + len(faults) + 20
        baro = bmp390.BaroStream.from_physical(rng.uniform(*bmp390.PRESSURE_RANGE_PA, m),
                                               rng.uniform(*bmp390.TEMPERATURE_RANGE_C, m),
                                               faults=faults)
        r = verilator_baro(baro, n + len(faults) + 8, work_dir=wd("baro"))
        out["baro"] = score_baro(baro, r) | {"nvm_reads": r.get("nvm_reads")}
    rng = np.random.default_rng(seed + 2)
    faults = {k: tfluna.FAULTS[(k // fault_every) % 5]
              for k in range(fault_every, n, fault_every)}
    m = n + len(faults)
    frames = tfluna.encode_frames(rng.uniform(0.2, 8.0, m), rng.integers(0, 3000, m),
                                  rng.uniform(-20, 60, m))
    if "lidar" in only:
        r = verilator_lidar(frames, faults, div=0, seed=seed, timeout_bits=200,
                            work_dir=wd("lidar"))
        out["lidar"] = score_lidar(tfluna.LidarStream(frames, faults, seed=seed), r)
    if "lidar_cocotbext" in only:
        r = verilator_lidar(frames[:n], None, source="cocotbext", div=0,
                            frame_period_s=15 * 10 / tfluna.BAUD, work_dir=wd("lidar_ext"))
        out["lidar_cocotbext"] = score_lidar(tfluna.LidarStream(frames[:n]), r)
    return out
