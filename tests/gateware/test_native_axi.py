"""The native AXI4-Lite co-simulation server (navgate.gateware.native_axi) on a small top: an
AxiLiteRegisterBank of a SystemRDL map plus an 80-bit input stream whose payloads are
accumulated into registers (sum, count, an order-sensitive checksum) and an ``irq`` that rises
a fixed delay after a threshold count. Checked against a Python model of the top and
navgate.hw.regmap.RegisterFileModel: strobed writes, SLVERR, stream order, poll/wait and their
timeouts, random channel delays and skews (same answers, more cycles), the Registers driver
over the transport, deferred batches, and the exact cycle count of a fixed sequence."""

from __future__ import annotations

import random

import numpy as np
import pytest
from amaranth import Cat, Const, Module, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.sim import Simulator

from navgate.gateware.axi_lite import AxiLiteRegisterBank, axi_lite_signature
from navgate.gateware.native_axi import (
    AxiResponseError,
    NativeAxiBus,
    NativeAxiError,
    NativeAxiSim,
)
from navgate.hw.regmap import OKAY, SLVERR, RegisterFileModel, Registers, load_rdl

RDL = """
addrmap axisim_test {
    default regwidth = 32;
    default accesswidth = 32;
    reg { field { sw = rw; hw = r; } value[31:0] = 0x01020304; } CTRL @ 0x0;
    reg { field { sw = rw; hw = r; } n[15:0] = 0; field { sw = rw; hw = r; } spare[23:16] = 0;
        } THRESH @ 0x4;
    reg { field { sw = r; hw = w; } value[31:0]; } SUM @ 0x8;
    reg { field { sw = r; hw = w; } value[31:0]; } COUNT @ 0xC;
    reg { field { sw = r; hw = w; } value[31:0]; } CHECK @ 0x10;
    reg { field { sw = w; hw = r; singlepulse; } clear[0:0] = 0; } CMD @ 0x14;
    reg { field { sw = r; hw = rw; hwset; onread = rclr; } done[0:0] = 0; } EVENT @ 0x18;
    reg { field { sw = r; hw = na; } id[31:0] = 0xA5150001; } ID @ 0x20;
};
"""

PAYLOAD = data.StructLayout({"a": unsigned(32), "b": signed(40), "tag": unsigned(8)})
IRQ_DELAY = 10  #: cycles from the threshold count to irq
M32 = 0xFFFFFFFF


class AccumulatorTop(wiring.Component):
    """Register bank + ``feed`` stream (ready every other cycle) + ``irq``, and ``bad``: a
    sticky flag of the master's rules (a valid dropped, or its payload changed, before the
    handshake on AW, W, AR or ``feed``)."""

    def __init__(self, regmap):
        self.regmap = regmap
        super().__init__({"axi": In(axi_lite_signature(regmap.address_width)),
                          "feed": In(stream.Signature(PAYLOAD)), "irq": Out(1),
                          "bad": Out(1)})

    def monitor(self, m):
        axi, feed = self.axi, self.feed
        channels = ((axi.awvalid, axi.awready, Cat(axi.awaddr, axi.awprot)),
                    (axi.wvalid, axi.wready, Cat(axi.wdata, axi.wstrb)),
                    (axi.arvalid, axi.arready, Cat(axi.araddr, axi.arprot)),
                    (feed.valid, feed.ready, feed.payload.as_value()))
        for valid, ready, payload in channels:
            pending = Signal()
            held = Signal(len(payload))
            m.d.sync += [pending.eq(valid & ~ready), held.eq(payload)]
            with m.If(pending & (~valid | (payload != held))):
                m.d.sync += self.bad.eq(1)

    def elaborate(self, platform):
        m = Module()
        m.submodules.bank = bank = AxiLiteRegisterBank(self.regmap)
        wiring.connect(m, wiring.flipped(self.axi), bank.axi)
        self.monitor(m)
        total, count, check = Signal(32), Signal(32), Signal(32)
        cool = Signal()
        p = self.feed.payload
        m.d.comb += self.feed.ready.eq(~cool)
        m.d.sync += cool.eq(0)
        with m.If(bank.p_CMD[0]):
            m.d.sync += [total.eq(0), count.eq(0), check.eq(0)]
        with m.Elif(self.feed.valid & self.feed.ready):
            b = p.b
            m.d.sync += [cool.eq(1), total.eq(total + p.a + b[:32]), count.eq(count + 1),
                         check.eq(Cat(check[31], check[:31]) ^ p.a ^ b[8:40]
                                  ^ Cat(Const(0, 24), p.tag))]
        thresh = bank.o_THRESH[:16]
        reached = Signal()
        timer = Signal(range(IRQ_DELAY + 1))
        irq_q = Signal()
        m.d.comb += reached.eq((thresh != 0) & (count >= thresh))
        with m.If(~reached):
            m.d.sync += timer.eq(0)
        with m.Elif(timer != IRQ_DELAY):
            m.d.sync += timer.eq(timer + 1)
        m.d.comb += self.irq.eq(timer == IRQ_DELAY)
        m.d.sync += irq_q.eq(self.irq)
        m.d.comb += [bank.i_SUM.eq(total), bank.i_COUNT.eq(count), bank.i_CHECK.eq(check),
                     bank.set_EVENT.eq(self.irq & ~irq_q)]
        return m


def accumulate(a, b, tag, state=(0, 0, 0)):
    """The top's registers (sum, count, check) after the payloads (a, b, tag)."""
    total, count, check = state
    for x, y, t in zip(a, b, tag, strict=True):
        y = int(y) & ((1 << 40) - 1)
        total = (total + int(x) + (y & M32)) & M32
        check = (((check << 1) | (check >> 31)) & M32) ^ int(x) ^ (y >> 8) ^ (int(t) << 24)
        count += 1
    return total, count, check


def random_payloads(rng, n):
    return {"a": rng.integers(0, 2**32, n, dtype=np.uint64),
            "b": rng.integers(-2**39, 2**39, n, dtype=np.int64),
            "tag": rng.integers(0, 256, n, dtype=np.uint64)}


@pytest.fixture(scope="module")
def regmap(tmp_path_factory):
    path = tmp_path_factory.mktemp("rdl") / "axisim_test.rdl"
    path.write_text(RDL)
    return load_rdl(path)


@pytest.fixture(scope="module")
def top(regmap):
    return AccumulatorTop(regmap)


def new_sim(top, **kw):
    return NativeAxiSim(top, streams=("feed",), watch=("irq", "bad"), top="axisim_test",
                        **kw)


def assert_rules_kept(sim):
    """The monitor's ``bad`` flag is low (waiting 0 cycles for it times out)."""
    with pytest.raises(NativeAxiError, match="wait for output 1 timed out"):
        sim.wait("bad", limit=0)


def test_exact_cycles_of_a_fixed_sequence(top, regmap):
    with new_sim(top) as sim:
        assert sim.cycles == 0
        sim.write(0x0, 0xDEADBEEF)           # AW+W, write, B: 3 cycles
        assert sim.cycles == 3
        assert sim.read(0x0) == 0xDEADBEEF   # AR, R: 2 cycles
        assert sim.cycles == 5
        sim.push("feed", {"a": [1, 2, 3], "b": [4, 5, 6], "tag": [7, 8, 9]})
        assert sim.cycles == 5 + 1 + 2 + 2   # ready low the cycle after each payload
        sim.run(7)
        assert sim.cycles == 17
        assert sim.read(0x8) == 21 and sim.read(0xC) == 3
    assert sim.final_cycles == 21


def test_registers_strobes_and_slverr(top, regmap):
    model = RegisterFileModel(regmap)
    with new_sim(top) as sim:
        assert sim.read(0x0) == 0x01020304 == model.read(0x0)[0]
        assert sim.read(0x20) == 0xA5150001
        sim.write(0x0, 0x11223344)
        assert sim.write(0x0, 0xAABBCCDD, strb=0b0101) == OKAY
        assert sim.read(0x0) == 0x11BB33DD
        assert sim.write(0x4, 0xFFFFFFFF, strb=0b1100) == OKAY
        assert sim.read(0x4) == 0x00FF0000  # spare[23:16] only: bits 31:24 are unmapped
        # unmapped offsets answer SLVERR: returned unchecked, raised checked
        assert sim.write(0x1C, 1, check=False) == SLVERR
        assert sim.read_resp(0x1C) == (0, SLVERR)
        assert sim.batch(["R 24", "W 3c 0 f", "R 20"]) == ["0/2", "2", "a5150001"]
        with pytest.raises(AxiResponseError, match="SLVERR reading offset 0x01C"):
            sim.read(0x1C)
        with pytest.raises(AxiResponseError, match="SLVERR writing offset 0x028"):
            sim.write(0x28, 5)
        # read-only registers ignore writes with OKAY
        assert sim.write(0x20, 0) == OKAY and sim.read(0x20) == 0xA5150001
        # random strobed traffic on every register against the bank's model
        for off, d, strb in ((0x0, 0x11223344, 0xF), (0x0, 0xAABBCCDD, 0b0101),
                             (0x4, 0xFFFFFFFF, 0b1100)):
            model.write(off, d, strb)
        rng = random.Random(5)
        # (not CMD, which clears the accumulator, nor EVENT, which is timing dependent)
        offsets = [o for o in regmap.by_offset if o not in (0x14, 0x18)] + [0x1C, 0x24, 0x3C]
        cmds, expect = [], []
        for _ in range(300):
            off = rng.choice(offsets)
            if rng.random() < 0.5:
                d, s = rng.getrandbits(32), rng.randrange(16)
                cmds.append(f"W {off:x} {d:x} {s:x}")
                expect.append(str(model.write(off, d, s)))
            else:
                v, r = model.read(off)
                cmds.append(f"R {off:x}")
                expect.append(f"{v:x}" + (f"/{r}" if r else ""))
        assert sim.batch(cmds) == expect


def test_stream_order_poll_wait_and_timeouts(top):
    rng = np.random.default_rng(11)
    first, second = random_payloads(rng, 150), random_payloads(rng, 50)
    with new_sim(top) as sim:
        sim.write(0x4, 200)                        # THRESH: irq after 200 payloads
        sim.push("feed", first)
        state = accumulate(first["a"], first["b"], first["tag"])
        assert (sim.read(0x8), sim.read(0xC), sim.read(0x10)) == state
        # wait and poll time out with a clear error after exactly their limits ...
        c0 = sim.cycles
        with pytest.raises(NativeAxiError, match=r"wait for output 0 timed out: low for 25"):
            sim.wait("irq", limit=25)
        assert sim.cycles - c0 == 25
        c0 = sim.cycles
        with pytest.raises(NativeAxiError, match=r"poll of 0xc timed out after 50 cycles: "
                                                 r"rdata 0x96 & mask 0xffffffff != 0xc8"):
            sim.poll(0xC, M32, 200, limit=50)
        assert sim.cycles - c0 == 50               # 25 reads of 2 cycles
        # ... and leave the model usable
        assert sim.read(0xC) == 150
        assert sim.read(0x18) == 0                 # EVENT not set yet
        sim.push(0, second)
        state = accumulate(second["a"], second["b"], second["tag"], state)
        assert sim.poll(0xC, 0xFF, 200 & 0xFF, limit=10) == 200
        assert sim.wait("irq", limit=100) == IRQ_DELAY - 2   # the poll read took 2 cycles
        assert sim.wait("irq") == 0                # still high
        assert (sim.read(0x8), sim.read(0xC), sim.read(0x10)) == state
        assert sim.read(0x18) == 1 and sim.read(0x18) == 0   # EVENT: set once, read-clear
        sim.write(0x14, 1)                         # CMD.clear
        assert sim.read(0xC) == 0 and sim.read(0x8) == 0
        assert_rules_kept(sim)


def test_wait_counts_exact_cycles(top):
    with new_sim(top) as sim:
        sim.write(0x4, 2)
        sim.push("feed", {"a": [1, 1], "b": [0, 0], "tag": [0, 0]})
        assert sim.wait("irq", limit=IRQ_DELAY) == IRQ_DELAY


def test_bad_batches_and_a_wedged_model(top):
    with new_sim(top) as sim:
        for bad, why in ((["X 1"], "unknown command 'X'"), (["W 0 1"], "needs 3 arguments"),
                         (["W 0 1 10"], "bad arguments"), (["S 1 0"], "bad arguments"),
                         (["S 0 " + "f" * 21], "bad arguments"), (["Q 2 5"], "bad arguments")):
            with pytest.raises(NativeAxiError, match=why):
                sim.batch(["W 0 5 f", *bad])
        assert sim.read(0x0) == 0x01020304 and sim.cycles == 2  # nothing ran
        with pytest.raises(ValueError, match="outside the 6-bit bus"):
            sim.read(0x40)
        with pytest.raises(ValueError, match="unknown fields"):
            sim.push("feed", {"a": 1, "b": 2, "tag": 3, "c": 4})
    with new_sim(top, limit=2) as sim:
        assert sim.read(0x0) == 0x01020304       # 2 cycles: within the limit
        with pytest.raises(NativeAxiError, match="no B response within 2 cycles"):
            sim.write(0x0, 1)
        with pytest.raises(NativeAxiError, match="wedged by an earlier timeout"):
            sim.read(0x0)


@pytest.mark.parametrize("options", [
    {"delay_probability": 0.5, "max_delay": 4, "seed": 3},
    {"delay_probability": 0.3, "max_delay": 2, "seed": 4, "skew": 2},
    {"skew": -3},
])
def test_random_channel_delays_give_the_same_answers(top, regmap, options):
    rng = random.Random(9)
    np_rng = np.random.default_rng(9)
    offsets = [0x0, 0x4, 0x8, 0xC, 0x10, 0x20, 0x1C]
    script = []
    for _ in range(120):
        if rng.random() < 0.15:
            pay = random_payloads(np_rng, rng.randrange(1, 4))
            script.append(("S", pay))
        elif rng.random() < 0.5:
            script.append(("W", rng.choice(offsets), rng.getrandbits(32), rng.randrange(16)))
        else:
            script.append(("R", rng.choice(offsets)))

    def play(sim):
        out = []
        for step in script:
            if step[0] == "S":
                sim.push("feed", step[1])
            elif step[0] == "W":
                out.append(sim.write(*step[1:], check=False))
            else:
                out.append(sim.read_resp(step[1]))
        return out, sim.cycles

    with new_sim(top) as sim:
        plain, plain_cycles = play(sim)
        assert_rules_kept(sim)
    with new_sim(top, **options) as sim:
        delayed, delayed_cycles = play(sim)
        assert_rules_kept(sim)
    assert delayed == plain
    assert delayed_cycles > plain_cycles
    assert sum(1 for r in plain if r == SLVERR or (isinstance(r, tuple) and r[1])) > 5


def test_monitor_catches_a_dropped_valid(regmap):
    """The rule monitor of the test top can fire (Amaranth simulation of a bad master)."""
    dut = AccumulatorTop(regmap)
    seen = []

    async def bench(ctx):
        ctx.set(dut.axi.awvalid, 1)      # taken at the first edge: the AW buffer fills
        await ctx.tick()
        await ctx.tick()                 # a second AW waits (awready low) ...
        seen.append(ctx.get(dut.bad))
        ctx.set(dut.axi.awvalid, 0)      # ... and is withdrawn: a rule violation
        await ctx.tick()
        seen.append(ctx.get(dut.bad))

    sim = Simulator(dut)
    sim.add_clock(1e-6)
    sim.add_testbench(bench)
    sim.run()
    assert seen == [0, 1]


def test_registers_driver_and_deferred_batches(top, regmap):
    rng = np.random.default_rng(2)
    pay = random_payloads(rng, 40)
    with new_sim(top, delay_probability=0.2, max_delay=2, seed=1) as sim:
        bus = NativeAxiBus(sim)
        regs = Registers(regmap, bus)
        regs.write("THRESH", n=40, spare=0x5A)
        assert regs.read_fields("THRESH") == {"n": 40, "spare": 0x5A}
        assert regs.read("ID") == 0xA5150001
        with pytest.raises(OSError, match="SLVERR reading offset 0x024"):
            bus.read(0x24)
        b0 = sim.batches
        with bus.deferred():
            for i in range(50):
                regs.write("CTRL", i)
            sim.push("feed", pay)
            sim.run(5)
            assert sim.batches == b0                       # nothing sent yet
            count = regs.read("COUNT")                     # flushes: one batch
            assert sim.batches == b0 + 1
            regs.write("CTRL", 0x1234)
        assert sim.batches == b0 + 2                       # the exit flushed the last write
        assert count == 40 and regs.read("CTRL") == 0x1234
        assert (regs.read("SUM"), regs.read("COUNT"), regs.read("CHECK")) == \
            accumulate(pay["a"], pay["b"], pay["tag"])
        assert sim.wait("irq", limit=100) <= IRQ_DELAY
        with pytest.raises(AxiResponseError, match="SLVERR writing offset 0x03C .deferred"):
            with sim.deferred():
                sim.write(0x0, 7)
                sim.write(0x3C, 7)
        assert sim.read(0x0) == 7                          # the writes before it happened
        assert_rules_kept(sim)


def test_a_bare_bank_without_streams_or_watched_outputs(top, regmap):
    with pytest.raises(NativeAxiError, match="has no port 'imu'"):
        NativeAxiSim(top, streams=("imu",))
    with pytest.raises(NativeAxiError, match="'feed' is not a 1-bit output"):
        NativeAxiSim(top, watch=("feed",))
    with pytest.raises(NativeAxiError, match="'irq' is not an input stream"):
        NativeAxiSim(top, streams=("irq",))
    with pytest.raises(NativeAxiError, match="addr_width 8 != the component's 6"):
        NativeAxiSim(top, addr_width=8)
    with NativeAxiSim(AxiLiteRegisterBank(regmap), top="axisim_bank") as sim:
        regs = Registers(regmap, NativeAxiBus(sim))
        regs.write("THRESH", 0x123456)
        assert regs.read("THRESH") == 0x123456 and regs.read("ID") == 0xA5150001
        assert sim.cycles == 3 + 2 + 2
        with pytest.raises(NativeAxiError, match="no stream 'feed'"):
            sim.push("feed", 1)
        with pytest.raises(NativeAxiError, match="output 'irq' is not watched"):
            sim.wait("irq")


def test_readings_polls_and_waits_queued_in_one_batch(top, regmap):
    """Under deferred, read_later, Registers.wait_until (the bus's poll) and the bus's wait go
    into the batch with the writes and pushes: one round trip, the Readings filled in when it
    is sent, a deferred SLVERR read or a poll timeout raised then; outside it, at once."""
    rng = np.random.default_rng(3)
    pay = random_payloads(rng, 12)
    with new_sim(top) as sim:
        bus = NativeAxiBus(sim)
        regs = Registers(regmap, bus)
        regs.write("THRESH", n=12, spare=0)
        b0, c0 = sim.batches, sim.commands
        with regs.deferred():
            before = regs.read_later("COUNT")
            bus.push("feed", pay)
            counted = regs.wait_until("COUNT", M32, 12, limit=1_000)
            irq = bus.wait("irq", 100)
            sums = [regs.read_later(r) for r in ("SUM", "COUNT", "CHECK")]
            assert not sums[0].ready and sim.batches == b0
            with pytest.raises(RuntimeError, match="has not been sent"):
                _ = sums[0].value
        assert (sim.batches, sim.commands) == (b0 + 1, c0 + 1 + 12 + 1 + 1 + 3)
        assert before.value == 0 and counted.value == 12
        assert 0 < irq.value <= IRQ_DELAY
        assert tuple(r.value for r in sums) == accumulate(pay["a"], pay["b"], pay["tag"])
        assert regs.read_later("COUNT").value == 12 and sim.batches == b0 + 2  # at once
        assert regs.wait_until("COUNT", 0xFF, 12, limit=10).value == 12
        with pytest.raises(AxiResponseError, match="SLVERR reading offset 0x024 .deferred"):
            with bus.deferred():
                bus.read_later(0x24)
        with pytest.raises(NativeAxiError, match="poll of 0xc timed out after 20 cycles"):
            with regs.deferred():
                regs.wait_until("COUNT", 0xFFFFFFFF, 13, limit=20)
        assert regs.read("COUNT") == 12                    # the model is still usable
