"""cocotb test of the Verilated ``altitude_profile_manager`` against cocotbext-axi's AXI RAM.

Loaded inside the simulator by :func:`navgate.gateware.verify.run_cocotb`; the job file named
by ``NAVGATE_PROFILE_JOB`` gives the seed, the number of rounds and where to write the
status. Each round pushes a random number of entries (each held on the stream until it is
taken), starts a DMA of a random count to a random 16-byte-aligned address, waits for
``done`` and compares the RAM with the newest entries; the AXI RAM model answers with
random back-pressure, and a monitor checks every burst against the Zynq HP-port rules (at
most 16 beats, INCR, 4-byte beats, no 4 KB crossing).
"""

import json
import os
import random

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import ReadOnly, RisingEdge
from cocotbext.axi import AxiRamWrite, AxiWriteBus

BOUNDARY = 4096


def _pauses(rng, probability):
    while True:
        yield rng.random() < probability


@cocotb.test()
async def profile_dma(dut):
    job = json.loads(open(os.environ["NAVGATE_PROFILE_JOB"]).read())
    rng = random.Random(job["seed"])
    status = {"rounds": 0, "entries_checked": 0, "bursts": 0, "violations": [],
              "mismatches": []}
    Clock(dut.clk, 10, unit="ns").start()
    dut.rst.value = 1
    dut.entry__valid.value = 0
    dut.dma_start.value = 0
    ram = AxiRamWrite(AxiWriteBus.from_prefix(dut, "axi_"), dut.clk, dut.rst, size=1 << 16)
    for channel in (ram.aw_channel, ram.w_channel, ram.b_channel):
        channel.set_pause_generator(_pauses(random.Random(rng.getrandbits(32)), 0.3))
    for _ in range(3):
        await RisingEdge(dut.clk)
    dut.rst.value = 0

    async def monitor():
        while True:
            await RisingEdge(dut.clk)
            await ReadOnly()
            if int(dut.axi__awvalid.value) and int(dut.axi__awready.value):
                address = int(dut.axi__awaddr.value)
                beats = int(dut.axi__awlen.value) + 1
                status["bursts"] += 1
                if beats > 16 or int(dut.axi__awburst.value) != 1 \
                        or int(dut.axi__awsize.value) != 2 \
                        or address // BOUNDARY != (address + 4 * beats - 1) // BOUNDARY:
                    status["violations"].append([address, beats])

    cocotb.start_soon(monitor())
    pushed = []
    for round_ in range(job["rounds"]):
        for _ in range(rng.randrange(0, 40)):
            entry = rng.getrandbits(121)  # h, pos_n, pos_e, time, valid; reserved zero
            dut.entry__payload.value = entry
            dut.entry__valid.value = 1
            while True:  # held until the stream takes it (one entry every four cycles)
                await ReadOnly()
                ready = int(dut.entry__ready.value)
                await RisingEdge(dut.clk)
                if ready:
                    break
            dut.entry__valid.value = 0
            pushed.append(entry)
            for _ in range(rng.randrange(3)):
                await RisingEdge(dut.clk)
        count = rng.randrange(0, 70)
        address = rng.randrange(0, (1 << 16) - 64 * 16) & ~15
        dut.dma_address.value = address
        dut.dma_count.value = count
        dut.dma_start.value = 1
        await RisingEdge(dut.clk)
        dut.dma_start.value = 0
        while True:
            await RisingEdge(dut.clk)
            await ReadOnly()
            if int(dut.done.value):
                error = int(dut.error.value)
                break
        await RisingEdge(dut.clk)
        n = min(count, len(pushed), 64)
        expected = pushed[len(pushed) - n:]
        data = ram.read(address, 16 * n) if n else b""
        got = [int.from_bytes(data[16 * i:16 * i + 16], "little") for i in range(n)]
        if got != expected or error:
            status["mismatches"].append([round_, address, count, n, error])
        status["rounds"] += 1
        status["entries_checked"] += n
    status["mismatches"] = status["mismatches"][:10]
    status["violations"] = status["violations"][:10]
    with open(job["status"], "w") as fh:
        json.dump(status, fh)
