"""opflow's phased scheduler and datapath (:mod:`navgate.opflow.phased`,
:mod:`navgate.opflow.phased_machine`) on a generic two-phase program: the datapath in
Amaranth's simulator bit for bit against :func:`navgate.opflow.execute.run_bittrue`, over
three runs in a row that carry a state register, with random and special operands; the
scheduler's rules checked on the schedule; its rejections."""

import numpy as np
import pytest
from amaranth.hdl import Module, Signal, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.sim import Simulator

from navgate.gateware.fp32 import Fp32Add, Fp32Div, Fp32Mul
from navgate.numerics.fp32 import f32_to_bits
from navgate.opflow.execute import run_bittrue
from navgate.opflow.ir import Builder
from navgate.opflow.phased import PhasedUnits, ScheduleError, build_schedule
from navgate.opflow.phased_machine import Control, PhasedDatapath


class _Hold(wiring.Component):
    """A client's own unit for the test: ``r = a`` two cycles later, and flag ``neg`` (the
    sign bit of ``a``); the scheduler issues it every 3 cycles."""

    LATENCY = 2

    def __init__(self):
        super().__init__({
            "i": In(stream.Signature(data.StructLayout({"a": unsigned(32)}))),
            "o": Out(stream.Signature(data.StructLayout({"r": unsigned(32),
                                                         "neg": unsigned(1)})))})

    def elaborate(self, platform):
        m = Module()
        a1, v1 = Signal(32), Signal()
        m.d.sync += [a1.eq(self.i.payload.a), v1.eq(self.i.valid),
                     self.o.payload.r.eq(a1), self.o.payload.neg.eq(a1[31]),
                     self.o.valid.eq(v1)]
        m.d.comb += self.i.ready.eq(1)
        return m


CORES = {"mul": Fp32Mul, "add": Fp32Add, "div": Fp32Div, "hold": _Hold}
UNITS = PhasedUnits(
    unit_of={"mul": "mul", "add": "add", "sub": "add", "div": "div", "hold": "hold"},
    latency={k: c.LATENCY for k, c in CORES.items()},
    ports={"mul": ("a", "b"), "add": ("a", "b"), "div": ("a", "b"), "hold": ("a",)},
    interval={"hold": 3})
CONTROLS = (Control("sub", 1, "add", "sub", {"sub": 1}),)
CONSTANTS = {"ONE": 0x3F800000}


def program():
    """Phase 1 (module "norm"): n = x x + y y, d = n - ONE, h = hold(y); phase 2 ("acc"):
    s_n = s + x / d (the state, read before it is written), out = (s_n * h) - x."""
    b = Builder("phased", inputs=("x", "y"), registers=("s",))
    b.module = "norm"
    n = b.add(b.mul("x", "x"), b.mul("y", "y"))
    d = b.sub(n, "ONE")
    h = b.op("hold", "y")
    b.module = "acc"
    s_n = b.op("add", "s", b.div("x", d), name="s_n")
    b.op("sub", b.mul(s_n, h), "x", name="out")
    b.prog.commit = {"s": "s_n"}
    b.prog.outputs = {"out": "out"}
    return b.prog


def schedule():
    return build_schedule(program().ops, ("x", "y", "s"), {"s_n": "s", "out": "out"}, UNITS,
                          phases=(("norm",), ("acc",)), constants=CONSTANTS)


def test_schedule_keeps_phases_latencies_and_banks():
    s = schedule()
    ops = {p.op.dst: p for p in s.ops}
    assert [tuple(p) for p in s.phases] == [("norm",), ("acc",)]
    (lo1, hi1), (lo2, hi2) = s.phase_windows
    assert lo1 == 0 and hi1 < lo2 <= hi2 == s.length - 1
    for p in s.ops:
        assert p.done == p.cycle + UNITS.latency[p.unit]
        for a in p.op.srcs:  # operands ready (bypass: in the cycle they leave the unit)
            if a in ops:
                assert ops[a].done <= p.cycle
    holds = sorted(p.cycle for p in s.ops if p.unit == "hold")
    assert len(holds) == 1 and s.unit_use()["hold"] == 1
    writes = [(p.done, p.dest[1]) for p in s.ops if p.dest[0] == "bank"]
    assert len(writes) == len(set(writes))  # one write per bank and cycle
    assert ops["s_n"].dest == ("ff", "s") and ops["out"].dest == ("ff", "out")
    # bypass timing, exact: the two muls issue in 0 and 1, the add when the second leaves
    # its unit, the sub when the add does; phase 2 starts after the last phase-1 write and
    # chains div, add (s_n), mul, sub
    L = UNITS.latency
    assert hi1 == 1 + L["mul"] + 2 * L["add"]
    assert s.length == hi1 + 1 + L["div"] + L["add"] + L["mul"] + L["add"] + 1

def _random_words(rng, n):
    special = [0, 0x80000000, 0x3F800000, 0xBF800000, 0x7F800000, 0xFF800000, 0x7FC00000,
               0x00800000, 0x7F7FFFFF, 0x00000001]
    x = np.concatenate([special, f32_to_bits(rng.normal(0, 3, n - len(special)))])
    return x.astype(np.uint32), f32_to_bits(rng.normal(0, 3, n)).astype(np.uint32)


def _simulate(s, runs):
    """Run the datapath once per (x, y) word pair; the parent (this testbench) holds the
    state register s and the output register, written where we_<reg> is high."""
    dut = PhasedDatapath(s, lambda u: CORES[u](), CONTROLS, {"hold_neg": ("hold", "neg")})
    got = []

    async def bench(ctx):
        await ctx.tick().repeat(2)  # the control word of cycle 0 is read while idle
        state = 0
        for x, y in runs:
            ctx.set(dut.src_x, int(x))
            ctx.set(dut.src_y, int(y))
            ctx.set(dut.src_s, state)
            ctx.set(dut.start, 1)
            await ctx.tick()
            ctx.set(dut.start, 0)
            regs, cycles, flag = {}, 0, 0
            while True:
                for r in dut.sink_regs:
                    if ctx.get(getattr(dut, f"we_{r}")):
                        regs[r] = ctx.get(getattr(dut, f"wd_{r}"))
                flag |= ctx.get(dut.hold_neg)
                last = ctx.get(dut.last)
                await ctx.tick()
                cycles += 1
                if last:
                    break
            state = regs["s"]
            got.append((regs, cycles, flag))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return got


def test_datapath_is_bit_exact_against_the_interpreter():
    rng = np.random.default_rng(28)
    s = schedule()
    xs, ys = _random_words(rng, 12)
    runs = list(zip(xs, ys, strict=True))
    got = _simulate(s, runs)
    prog = program()
    state = np.uint32(0)
    for (x, y), (regs, cycles, flag) in zip(runs, got, strict=True):
        new, out, _ = run_bittrue(prog, {"s": state}, {"x": x, "y": y, **CONSTANTS},
                                  kinds={"hold": lambda a: a})
        assert cycles == s.length
        assert regs["s"] == int(new["s"][0])
        assert regs["out"] == int(out["out"][0])
        assert flag == int(y) >> 31
        state = new["s"][0]


def test_rejections():
    ops = program().ops
    sinks = {"s_n": "s", "out": "out"}
    phases = (("norm",), ("acc",))
    with pytest.raises(ScheduleError, match="neither produced nor a source"):
        build_schedule(ops, ("x", "y"), sinks, UNITS, phases, CONSTANTS)
    with pytest.raises(ScheduleError, match="modules in no phase: acc"):
        build_schedule(ops, ("x", "y", "s"), sinks, UNITS, (("norm",),), CONSTANTS)
    with pytest.raises(ScheduleError, match="op kinds without a unit: hold"):
        units = PhasedUnits({"mul": "mul", "add": "add", "sub": "add", "div": "div"},
                            UNITS.latency, UNITS.ports)
        build_schedule(ops, ("x", "y", "s"), sinks, units, phases, CONSTANTS)
    with pytest.raises(ScheduleError, match="sink nope is not produced"):
        build_schedule(ops, ("x", "y", "s"), {**sinks, "nope": "r"}, UNITS, phases,
                       CONSTANTS)
    with pytest.raises(ValueError, match="unknown kind 'hold'"):
        run_bittrue(program(), {"s": 0}, {"x": 0, "y": 0, **CONSTANTS})
