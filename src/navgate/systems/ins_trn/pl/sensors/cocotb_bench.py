"""cocotb tests of the sensor interfaces' emitted Verilog (Verilator), with the same bit-level
device models as the Amaranth runs (loaded by :mod:`.verilator_bench`; the job file named by
``NAVGATE_SENSOR_JOB`` says what to run, ``result.json`` next to it receives the outcome).

* ``imu_stream`` / ``baro_stream``: the ADIS16500 / BMP390 SPI slave models on the pins,
  driven by pin-change triggers (one Python call per pin edge);
* ``lidar_stream``: the TF-Luna UART line from ``navgate.devices.tfluna`` (faults included) or,
  for clean streams, from ``cocotbext.uart.UartSource`` - an independent UART model.
"""

import json
import os

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import Edge, First, RisingEdge, Timer
from cocotb.utils import get_sim_time


def _job():
    path = os.environ["NAVGATE_SENSOR_JOB"]
    with open(path) as fh:
        return path, json.load(fh)


def _fields(value: int, layout):
    out = {}
    pos = 0
    for name, width, signed in layout:
        v = (value >> pos) & ((1 << width) - 1)
        if signed and v >> (width - 1):
            v -= 1 << width
        out[name] = v
        pos += width
    return out


async def _reset(dut, period_ps):
    Clock(dut.clk, period_ps, unit="ps").start()
    dut.rst.value = 1
    for _ in range(2):
        await RisingEdge(dut.clk)
    dut.rst.value = 0


async def _spi_slave(dut, model):
    dut.miso.value = 1
    while True:
        await First(Edge(dut.cs_n), Edge(dut.sclk), Edge(dut.mosi))
        t = get_sim_time("ps") * 1e-12
        dut.miso.value = model.pins(t, int(dut.cs_n.value), int(dut.sclk.value),
                                    int(dut.mosi.value))


async def _collect(dut, layout, got):
    while True:
        await RisingEdge(dut.o__valid)
        got.append(_fields(int(dut.o__payload.value), layout))


async def _spi_run(dut, model, job):
    path, _ = _job()
    await _reset(dut, job["period_ps"])
    dut.cfg_spi_div.value = job["div"]
    dut.cfg_rate.value = job["rate"]
    dut.cfg_enable.value = 1
    dut.o__ready.value = 1
    got = []
    cocotb.start_soon(_spi_slave(dut, model))
    cocotb.start_soon(_collect(dut, job["layout"], got))
    await Timer(job["period_ps"] * job["cycles"], unit="ps")
    result = {
        "got": got, "served": model.served,
        "violations": [[v.time, v.code, v.message] for v in model.violations],
        "sample_count": int(dut.sample_count.value), "error_count": int(dut.error_count.value),
    }
    if hasattr(model, "nvm_reads"):
        result["nvm_reads"] = model.nvm_reads
    with open(os.path.join(os.path.dirname(path), "result.json"), "w") as fh:
        json.dump(result, fh)


@cocotb.test()
async def imu_stream(dut):
    from navgate.devices import adis16500

    _, job = _job()
    st = adis16500.ImuStream(np.array(job["gyro"]), np.array(job["accel"]),
                             temp=np.array(job["temp"]),
                             faults={int(k): v for k, v in job["faults"].items()})
    await _spi_run(dut, adis16500.Adis16500Model(st), job)


@cocotb.test()
async def baro_stream(dut):
    from navgate.devices import bmp390

    _, job = _job()
    st = bmp390.BaroStream(np.array(job["up"]), np.array(job["ut"]),
                           faults={int(k): v for k, v in job["faults"].items()})
    await _spi_run(dut, bmp390.Bmp390Model(st), job)


@cocotb.test()
async def lidar_stream(dut):
    from navgate.devices import tfluna

    path, job = _job()
    await _reset(dut, job["period_ps"])
    dut.cfg_div.value = job["div"]
    dut.cfg_enable.value = 1
    dut.o__ready.value = 1
    dut.rx.value = 1
    got = []
    cocotb.start_soon(_collect(dut, job["layout"], got))
    frames = np.array(job["frames"], np.uint8)
    t_start = get_sim_time("ps")
    if job["source"] == "cocotbext":
        from cocotbext.uart import UartSource

        src = UartSource(dut.rx, baud=tfluna.BAUD, bits=8, stop_bits=1)
        gap = int(round(job["frame_period_s"] * 1e12))
        for k, frame in enumerate(frames):
            await src.write(bytes(frame))
            await src.wait()
            now = get_sim_time("ps")
            target = t_start + (k + 1) * gap
            if target > now:
                await Timer(target - now, unit="ps")
    else:
        st = tfluna.LidarStream(frames, {int(k): v for k, v in job["faults"].items()},
                                seed=job["seed"])
        tr, end = tfluna.stream_transitions(st, frame_period=job["frame_period_s"])
        for t, level in tr:
            target = t_start + int(round(t * 1e12))
            now = get_sim_time("ps")
            if target > now:
                await Timer(target - now, unit="ps")
            dut.rx.value = level
    await Timer(int(job["tail_s"] * 1e12), unit="ps")
    result = {"got": got}
    for n in ("byte_count", "frame_count", "checksum_errors", "framing_errors",
              "unreliable_count", "timeout_count", "overrun_count"):
        result[n] = int(getattr(dut, n).value)
    with open(os.path.join(os.path.dirname(path), "result.json"), "w") as fh:
        json.dump(result, fh)
