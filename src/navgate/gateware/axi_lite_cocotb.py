"""cocotb test of a Verilated AXI4-Lite register bank (navgate.gateware.axi_lite).

Loaded inside the simulator by :func:`navgate.gateware.verify.run_cocotb`; the job file named
by ``NAVGATE_AXIL_JOB`` gives the SystemRDL source, the seed, the number of random
transactions and where to write the status. The master is ``cocotbext-axi``'s
``AxiLiteMaster`` with seeded random pauses on all five channels (so AW and W arrive in either
order and B/R are back-pressured). Phases:

1. every register through the Python driver (:class:`navgate.hw.regmap.Registers`) over a bus
   that bridges its blocking calls into the simulation (``cocotb.task.bridge``/``resume``):
   each readable register read, each writable one written and read back;
2. random transactions (reads and writes with random byte strobes, unmapped offsets, fabric
   inputs and hardware set events changing between them), every response compared with
   :class:`navgate.hw.regmap.RegisterFileModel`, and every write-1 strobe checked.

The status JSON lists the counts and the first mismatches.
"""

import json
import os
import random

import cocotb
from cocotb.clock import Clock
from cocotb.task import bridge, resume
from cocotb.triggers import RisingEdge
from cocotbext.axi import AxiLiteBus, AxiLiteMaster

from navgate.hw.regmap import OKAY, SLVERR, RegisterFileModel, Registers, load_rdl


def _pauses(rng, probability):
    while True:
        yield rng.random() < probability


class _BridgedBus:
    """A blocking ``read``/``write`` bus for the driver, run from a bridge thread."""

    def __init__(self, master):
        self._master = master
        self.responses = []

    def read(self, offset):
        async def go():
            return await self._master.read(offset, 4)
        resp = resume(go)()
        self.responses.append(int(resp.resp))
        if int(resp.resp) != OKAY:
            raise OSError(f"SLVERR at 0x{offset:03X}")
        return int.from_bytes(resp.data, "little")

    def write(self, offset, value):
        async def go():
            return await self._master.write(offset, int(value).to_bytes(4, "little"))
        resp = resume(go)()
        self.responses.append(int(resp.resp))
        if int(resp.resp) != OKAY:
            raise OSError(f"SLVERR at 0x{offset:03X}")


@cocotb.test()
async def axi_lite_bank(dut):
    job = json.loads(open(os.environ["NAVGATE_AXIL_JOB"]).read())
    regmap = load_rdl(job["rdl"])
    rng = random.Random(job["seed"])
    model = RegisterFileModel(regmap)
    status = {"mismatches": [], "driver_reads": 0, "driver_writes": 0, "reads": 0,
              "writes": 0, "slverr": 0, "pulses_seen": 0}

    Clock(dut.clk, 10, unit="ns").start()
    dut.rst.value = 1
    inputs = [r for r in regmap.registers if r.hw_input_mask]
    settable = [r for r in regmap.registers if r.hw_set_mask]
    pulsed = [r for r in regmap.registers if r.pulse_mask]
    for reg in inputs:
        getattr(dut, f"i_{reg.name}").value = 0
    for reg in settable:
        getattr(dut, f"set_{reg.name}").value = 0
    master = AxiLiteMaster(AxiLiteBus.from_prefix(dut, "axi_"), dut.clk, dut.rst)
    for _ in range(3):
        await RisingEdge(dut.clk)
    dut.rst.value = 0
    await RisingEdge(dut.clk)
    p = job["pause_probability"]
    for channel in (master.write_if.aw_channel, master.write_if.w_channel,
                    master.write_if.b_channel, master.read_if.ar_channel,
                    master.read_if.r_channel):
        channel.set_pause_generator(_pauses(random.Random(rng.getrandbits(32)), p))

    seen_pulses = {}

    async def watch_pulses():
        while True:
            await RisingEdge(dut.clk)
            for reg in pulsed:
                value = int(getattr(dut, f"p_{reg.name}").value)
                if value:
                    status["pulses_seen"] += 1
                    seen_pulses.setdefault(reg.name, []).append(value)

    cocotb.start_soon(watch_pulses())

    # 1. every register through the driver
    bus = _BridgedBus(master)
    regs = Registers(regmap, bus)

    def through_driver():
        for reg in regmap.registers:
            if reg.read_mask:
                value = regs.read(reg.name)
                status["driver_reads"] += 1
                expected, _ = model.read(reg.offset)
                if value != expected:
                    status["mismatches"].append(["driver read", reg.name, value, expected])
            if reg.writable:
                value = rng.getrandbits(32)
                regs.write(reg.name, value)
                model.write(reg.offset, value)
                status["driver_writes"] += 1
                if reg.read_mask:
                    back = regs.read(reg.name)
                    status["driver_reads"] += 1
                    expected, _ = model.read(reg.offset)
                    if back != expected:
                        status["mismatches"].append(["driver readback", reg.name, back,
                                                     expected])
        try:
            bus.read(0x030)
            status["mismatches"].append(["unmapped read answered OKAY"])
        except OSError:
            status["slverr"] += 1

    await bridge(through_driver)()

    # 2. random transactions against the model
    offsets = [r.offset for r in regmap.registers]
    unmapped = [o for o in range(0, 1 << regmap.address_width, 4) if o not in regmap.by_offset]
    for _ in range(job["transactions"]):
        for reg in rng.sample(inputs, 2):
            value = rng.getrandbits(32)
            getattr(dut, f"i_{reg.name}").value = value
            model.hw_inputs[reg.name] = value
        if settable and rng.random() < 0.2:
            reg = rng.choice(settable)
            bits = rng.getrandbits(32)
            getattr(dut, f"set_{reg.name}").value = bits
            await RisingEdge(dut.clk)
            getattr(dut, f"set_{reg.name}").value = 0
            model.hw_set(reg.name, bits)
        await RisingEdge(dut.clk)
        offset = rng.choice(unmapped) if rng.random() < 0.05 else rng.choice(offsets)
        if rng.random() < 0.5:
            # a random contiguous byte range inside the word: the master derives wstrb
            first = rng.randrange(4)
            length = rng.randrange(1, 5 - first)
            data = bytes(rng.getrandbits(8) for _ in range(length))
            resp = await master.write(offset + first, data)
            word = int.from_bytes(bytes(first) + data + bytes(4 - first - length), "little")
            strb = ((1 << length) - 1) << first
            expected = model.write(offset, word, strb)
            status["writes"] += 1
            if int(resp.resp) != expected:
                status["mismatches"].append(["bresp", offset, int(resp.resp), expected])
        else:
            resp = await master.read(offset, 4)
            expected_data, expected_resp = model.read(offset)
            status["reads"] += 1
            got = int.from_bytes(resp.data, "little") if int(resp.resp) == OKAY else 0
            if int(resp.resp) != expected_resp or (expected_resp == OKAY
                                                   and got != expected_data):
                status["mismatches"].append(["read", offset, got, int(resp.resp),
                                             expected_data, expected_resp])
        if expected_resp_is_slverr(resp):
            status["slverr"] += 1
    for _ in range(4):
        await RisingEdge(dut.clk)
    if seen_pulses != model.pulses:
        status["mismatches"].append(["pulses", {k: len(v) for k, v in seen_pulses.items()},
                                     {k: len(v) for k, v in model.pulses.items()}])
    status["mismatches"] = status["mismatches"][:20]
    with open(job["status"], "w") as fh:
        json.dump(status, fh)


def expected_resp_is_slverr(resp):
    return int(resp.resp) == SLVERR
