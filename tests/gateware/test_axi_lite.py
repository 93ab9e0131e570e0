"""AXI4-Lite register bank (navgate.gateware.axi_lite) in Amaranth's simulator, against the
transaction-level model navgate.hw.regmap.RegisterFileModel, with a seeded random master that
delays every channel independently (AW before W, W before AW, slow B and R ready)."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from amaranth.sim import Simulator

from navgate.gateware.axi_lite import AxiLiteRegisterBank, sim_response, sim_write
from navgate.hw.regmap import OKAY, SLVERR, RegisterFileModel, load_rdl

RDL = (Path(__file__).resolve().parents[2] / "src" / "navgate" / "systems" / "ins_trn" / "pl"
       / "registers.rdl")


@pytest.fixture(scope="module")
def regmap():
    return load_rdl(RDL)


async def _wait_handshake(ctx, valid, ready):
    """Hold ``valid`` high until ``ready`` is sampled high at a clock edge."""
    ctx.set(valid, 1)
    while True:
        _, _, r = await ctx.tick().sample(ready)
        if r:
            ctx.set(valid, 0)
            return


def run_random_transactions(regmap, n, seed):
    dut = AxiLiteRegisterBank(regmap)
    model = RegisterFileModel(regmap)
    rng = random.Random(seed)
    axi = dut.axi
    offsets = [r.offset for r in regmap.registers]
    unmapped = [o for o in range(0, 1 << regmap.address_width, 4) if o not in regmap.by_offset]
    inputs = [r for r in regmap.registers if r.hw_input_mask]
    settable = [r for r in regmap.registers if r.hw_set_mask]
    log = {"mismatches": [], "reads": 0, "writes": 0, "slverr": 0, "pulses": 0}

    async def testbench(ctx):
        for _ in range(n):
            # fabric inputs change between transactions
            for reg in rng.sample(inputs, 3):
                value = rng.getrandbits(32)
                ctx.set(getattr(dut, f"i_{reg.name}"), value)
                model.hw_inputs[reg.name] = value
            if settable and rng.random() < 0.3:
                reg = rng.choice(settable)
                bits = rng.getrandbits(32)
                ctx.set(getattr(dut, f"set_{reg.name}"), bits)
                await ctx.tick()
                ctx.set(getattr(dut, f"set_{reg.name}"), 0)
                model.hw_set(reg.name, bits)
            offset = rng.choice(unmapped) if rng.random() < 0.05 else rng.choice(offsets)
            offset |= rng.randrange(4) if rng.random() < 0.1 else 0  # unaligned: word access
            if rng.random() < 0.5:
                data, strb = rng.getrandbits(32), rng.choice([0xF, 0xF, rng.randrange(16)])
                ctx.set(axi.awaddr, offset)
                ctx.set(axi.wdata, data)
                ctx.set(axi.wstrb, strb)
                first_aw = rng.random() < 0.5
                for which in ((0, 1) if first_aw else (1, 0)):
                    for _ in range(rng.randrange(3)):
                        await ctx.tick()
                    if which == 0:
                        await _wait_handshake(ctx, axi.awvalid, axi.awready)
                    else:
                        await _wait_handshake(ctx, axi.wvalid, axi.wready)
                for _ in range(rng.randrange(4)):
                    await ctx.tick()
                bresp = await sim_response(ctx, axi)
                # the write strobe, if any, is visible one cycle after the write
                expect = model.write(offset & ~3, data, strb)
                log["writes"] += 1
                if bresp != expect:
                    log["mismatches"].append(("bresp", hex(offset), bresp, expect))
                if expect == SLVERR:
                    log["slverr"] += 1
            else:
                ctx.set(axi.araddr, offset)
                for _ in range(rng.randrange(3)):
                    await ctx.tick()
                await _wait_handshake(ctx, axi.arvalid, axi.arready)
                expect_data, expect_resp = model.read(offset & ~3)
                for _ in range(rng.randrange(4)):
                    _, _, rvalid, rdata = await ctx.tick().sample(axi.rvalid, axi.rdata)
                    # while the master is not ready the response holds
                    if rvalid and rdata != expect_data:
                        log["mismatches"].append(("rdata held", hex(offset), rdata))
                ctx.set(axi.rready, 1)
                while True:
                    _, _, rvalid, rdata, rresp = await ctx.tick().sample(
                        axi.rvalid, axi.rdata, axi.rresp)
                    if rvalid:
                        break
                ctx.set(axi.rready, 0)
                log["reads"] += 1
                if (rdata, rresp) != (expect_data, expect_resp):
                    log["mismatches"].append(("read", hex(offset), hex(rdata), rresp,
                                              hex(expect_data), expect_resp))

    async def pulse_monitor(ctx):
        pulsed = [r for r in regmap.registers if r.pulse_mask]
        async for _, _, *values in ctx.tick().sample(
                *[getattr(dut, f"p_{r.name}") for r in pulsed]):
            for reg, value in zip(pulsed, values, strict=True):
                if value:
                    log["pulses"] += 1
                    seen = log.setdefault("seen_pulses", {}).setdefault(reg.name, [])
                    seen.append(value)
                    # the model records a pulse when the testbench takes the B response, which
                    # may be some cycles after the pulse: at most this one pulse is ahead of
                    # the model (the lists are compared in order at the end)
                    if len(seen) > len(model.pulses.get(reg.name, [])) + 1:
                        log["mismatches"].append(("unexpected pulse", reg.name, value))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.add_testbench(pulse_monitor, background=True)
    sim.run()
    return log, model


def test_random_transactions_match_the_model(regmap):
    log, model = run_random_transactions(regmap, 1500, seed=1)
    assert log["mismatches"] == []
    assert log["reads"] > 600 and log["writes"] > 600 and log["slverr"] > 20
    # every write-1 strobe the model expects was seen once, in order, with its mask
    seen = log.get("seen_pulses", {})
    assert {k: v for k, v in model.pulses.items()} == seen
    assert sum(len(v) for v in seen.values()) > 10


def test_reset_values_and_constants(regmap):
    model = RegisterFileModel(regmap)
    assert model.peek("ID") == 0x4E415647
    assert model.peek("UPDATE_RATE") == 2500
    assert model.peek("LIDAR_CFG") == 868
    assert model.read(0x00C)[1] == OKAY
    assert model.read(0x030) == (0, SLVERR)


def test_read_to_clear_keeps_an_event_of_the_same_cycle(regmap):
    """IRQ_STATUS: a hardware set in the very cycle of the read is returned by the next read."""
    dut = AxiLiteRegisterBank(regmap)
    axi = dut.axi
    offset = regmap["IRQ_STATUS"].offset
    reads = []

    async def testbench(ctx):
        ctx.set(dut.set_IRQ_STATUS, 0b01)
        await ctx.tick()
        ctx.set(dut.set_IRQ_STATUS, 0)
        for event in (0b10, 0):
            ctx.set(axi.araddr, offset)
            ctx.set(axi.arvalid, 1)
            ctx.set(dut.set_IRQ_STATUS, event)  # same cycle as the AR handshake
            await ctx.tick()
            ctx.set(axi.arvalid, 0)
            ctx.set(dut.set_IRQ_STATUS, 0)
            ctx.set(axi.rready, 1)
            _, _, rdata = await ctx.tick().sample(axi.rdata)
            ctx.set(axi.rready, 0)
            reads.append(rdata)
        ctx.set(axi.araddr, offset)
        ctx.set(axi.arvalid, 1)
        await ctx.tick()
        ctx.set(axi.arvalid, 0)
        ctx.set(axi.rready, 1)
        _, _, rdata = await ctx.tick().sample(axi.rdata)
        reads.append(rdata)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    assert reads == [0b01, 0b10, 0b00]


def test_reset_after_writes_reads_the_reset_values(regmap):
    """A reset in mid-run: every register reads its reset value again, although the plain
    32-bit registers are read from a distributed-RAM copy that a reset does not clear (the
    bank tracks which were written since reset); the first write after reset with a partial
    byte strobe reads back 0 in the bytes it left out."""
    from amaranth import ClockDomain, Module

    from navgate.gateware.axi_lite import ram_registers

    mirrored = ram_registers(regmap)
    assert len(mirrored) >= AxiLiteRegisterBank.RAM_MIN  # the map exercises the RAM copy
    # the fabric's read port of the copy reads what the bus reads, reset included
    dut = AxiLiteRegisterBank(regmap, fabric_reads=tuple(r.name for r in mirrored))
    top = Module()
    top.domains.sync = cd = ClockDomain()
    top.submodules.dut = dut
    axi = dut.axi
    rng = random.Random(7)
    writable = [r for r in regmap.registers if r.writable]
    results = {"before": {}, "after": {}, "partial": [], "fabric": []}

    def fabric(ctx, model, phase):
        for reg in mirrored:
            ctx.set(dut.fr_word, reg.offset >> 2)
            results["fabric"].append((phase, reg.name, ctx.get(dut.fr_data),
                                      model.read(reg.offset)[0]))

    async def write(ctx, offset, data, strb=0xF):
        return await sim_write(ctx, axi, offset, data, strb)

    async def read(ctx, offset):
        ctx.set(axi.araddr, offset)
        ctx.set(axi.arvalid, 1)
        await ctx.tick()
        ctx.set(axi.arvalid, 0)
        ctx.set(axi.rready, 1)
        _, _, rdata, rresp = await ctx.tick().sample(axi.rdata, axi.rresp)
        ctx.set(axi.rready, 0)
        return rdata, rresp

    async def testbench(ctx):
        model = RegisterFileModel(regmap)
        for reg in writable:
            data = rng.getrandbits(32)
            assert await write(ctx, reg.offset, data) == model.write(reg.offset, data)
        for reg in regmap.registers:
            results["before"][reg.name] = (await read(ctx, reg.offset), model.read(reg.offset))
        fabric(ctx, model, "before")
        ctx.set(cd.rst, 1)
        await ctx.tick()
        ctx.set(cd.rst, 0)
        model = RegisterFileModel(regmap)
        for reg in regmap.registers:
            results["after"][reg.name] = (await read(ctx, reg.offset), model.read(reg.offset))
        fabric(ctx, model, "after")
        for reg, strb in zip(mirrored[:5], (0b0001, 0b0010, 0b0100, 0b1000, 0b0000),
                             strict=True):
            data = rng.getrandbits(32)
            await write(ctx, reg.offset, data, strb)
            model.write(reg.offset, data, strb)
            results["partial"].append((await read(ctx, reg.offset), model.read(reg.offset)))
        fabric(ctx, model, "partial")

    sim = Simulator(top)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    for phase in ("before", "after"):
        bad = {k: v for k, v in results[phase].items() if v[0] != v[1]}
        assert not bad, (phase, bad)
    # the writes made the mirrored registers nonzero before the reset, and zero after it
    assert sum(results["before"][r.name][0][0] != 0 for r in mirrored) >= len(mirrored) - 1
    assert all(results["after"][r.name][0] == (0, OKAY) for r in mirrored)
    assert all(got == want for got, want in results["partial"]), results["partial"]
    assert [got[0] != 0 for got, _ in results["partial"]][:4].count(True) >= 3
    bad = [f for f in results["fabric"] if f[2] != f[3]]
    assert not bad, bad[:5]
    assert sum(f[2] != 0 for f in results["fabric"] if f[0] == "before") >= len(mirrored) - 1


@pytest.mark.filterwarnings("ignore::amaranth.hdl._ir.UnusedElaboratable")
def test_fabric_reads_need_registers_of_the_ram_copy(regmap):
    with pytest.raises(ValueError, match="RAM copy.*STATUS"):
        AxiLiteRegisterBank(regmap, fabric_reads=("TRN_POS_N", "STATUS"))


def test_ram_index_gives_distinct_rows_to_the_mirrored_registers(regmap):
    from navgate.gateware.axi_lite import ram_index, ram_registers

    words = tuple(r.offset >> 2 for r in ram_registers(regmap))
    rows = ram_index(words, regmap.address_width - 2)
    assert rows is not None and len(rows) == 6  # 42 registers in a 64-deep copy
    indices = {sum((bin(w & row).count("1") & 1) << i for i, row in enumerate(rows))
               for w in words}
    assert len(indices) == len(words)
    assert all(1 <= bin(row).count("1") <= 3 for row in rows)
    # 65 words need 7 index bits; single address bits come first
    assert len(ram_index(tuple(range(65)), 9)) == 7
    assert ram_index((0, 1, 2), 9) == (0b1, 0b10)
