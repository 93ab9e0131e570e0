"""cocotb test of the TinyKalman chip in Verilator: MPU-6500 device model on the SPI pins,
``cocotbext-uart`` on TX (started by :func:`navgate.systems.tinykalman.rtl_sim.run_verilator`).

The job file named by ``NAVGATE_TK_JOB`` gives the sample words, the chip's parameters, the
faults to inject and where to write the results. The device model
(:class:`navgate.devices.mpu6500.Mpu6500Bus`) runs on pin changes only (CS_N, SCLK, MOSI), so
Python is woken a few hundred times per sample, not every clock. ``UartSink`` (cocotbext-uart)
decodes the TX line; a second coroutine time-stamps each packet's first start bit for the
latency figure.
The wrapper generates the clock (Verilator ``--timing``).
"""

import json
import logging
import os
import time

import cocotb
from cocotb.triggers import FallingEdge, Timer, with_timeout
from cocotb.utils import get_sim_time
from cocotbext.uart import UartSink

from navgate.devices.mpu6500 import Mpu6500Bus, SpiTiming

PACKET_LEN = 6


@cocotb.test()
async def tinykalman_stream(dut):
    job = json.loads(open(os.environ["NAVGATE_TK_JOB"]).read())
    samples = []
    with open(job["samples"]) as fh:
        for line in fh:
            if line.strip():
                samples.append(tuple(int(v) for v in line.split()))
    n = job["n_samples"]
    clk_ns = job["clk_ns"]
    bit_ns = job["baud_div"] * clk_ns
    timing = SpiTiming(**job["timing"]) if job["timing"] else None
    faults = {int(k): v for k, v in job["faults"].items()}
    dev = Mpu6500Bus(samples, timing=timing)

    dut.rst_n.value = 0
    dut.miso.value = 0
    sink = UartSink(dut.tx, baud=1e9 / bit_ns, bits=8, stop_bits=1)
    logging.getLogger(f"cocotb.{dut.tx._path}").setLevel(logging.WARNING)
    await Timer(2 * clk_ns, "ns")
    await FallingEdge(dut.clk)  # the wrapper's clock
    dut.rst_n.value = 1
    t_start = get_sim_time("ns")

    cs_rises = []
    starts = []

    async def device():
        miso = 0
        prev_cs = 1
        spi = dut.spi
        change = spi.value_change
        while True:
            await change
            t = get_sim_time("ns") - t_start
            pins = int(spi.value)
            cs_n = pins >> 2
            if prev_cs and not cs_n:
                k, r = divmod(dev.stats.transactions, 2)
                if r == 0 and k in faults:
                    dev.set_fault(faults[k])
            if cs_n and not prev_cs:
                cs_rises.append(t)
            prev_cs = cs_n
            new = dev.pins(t, cs_n, (pins >> 1) & 1, pins & 1)
            if new != miso:
                dut.miso.value = new
                miso = new

    async def packet_starts():
        while True:
            await FallingEdge(dut.tx)
            starts.append(get_sim_time("ns") - t_start)
            await Timer((10 * PACKET_LEN - 0.5) * bit_ns, "ns")

    async def collect():
        data = bytearray()
        while len(data) < PACKET_LEN * n:
            data += await sink.read()
        return data

    cocotb.start_soon(device())
    cocotb.start_soon(packet_starts())
    error = None
    data = bytearray()
    wall = time.perf_counter()
    try:
        data = await with_timeout(collect(), (n + 2) * job["period"] * clk_ns, "ns")
    except Exception as exc:  # noqa: BLE001 - reported to the caller through the result file
        error = f"{type(exc).__name__}: {exc}"
    wall = time.perf_counter() - wall
    cycles = int((get_sim_time("ns") - t_start) // clk_ns)
    bursts = cs_rises[1::2]  # CS_N rising at the end of each burst (WHO_AM_I ends are even)
    latencies = [int((s - c) // clk_ns) for c, s in zip(bursts, starts, strict=False)]
    with open(job["uart"], "wb") as fh:
        fh.write(bytes(data))
    st = dev.stats
    with open(job["out"], "w") as fh:
        json.dump({
            "error": error, "cycles": cycles, "latencies": latencies[:n],
            "log": [[a, bool(r), b.hex()] for a, r, b in dev.log],
            "violations": st.violations, "violation_count": dev.violation_count,
            "stats": {"transactions": st.transactions, "bursts": st.bursts,
                      "who_am_i_reads": st.who_am_i_reads, "underruns": st.underruns},
            "seconds": wall,
        }, fh)
