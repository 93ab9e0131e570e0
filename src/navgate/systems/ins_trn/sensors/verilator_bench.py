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
            runner.test(test_module="navgate.systems.ins_trn.sensors.cocotb_bench",
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
