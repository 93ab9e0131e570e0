"""The scheduled float32 datapath (navgate.gateware.scheduled): exact cycle counts of small
programs, schedule invariants, and bit-exact execution of a random program with special
values in Amaranth simulation against navgate.numerics.fp32."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest
from amaranth.sim import Simulator

from navgate.gateware.scheduled import (
    UNIT_LATENCY,
    MachineImage,
    ScheduledMachine,
    ScheduleError,
    Units,
    schedule_program,
)
from navgate.numerics import fp32 as F


@dataclass(frozen=True)
class Op:
    dst: str
    kind: str
    srcs: tuple
    module: str = "m"


@dataclass
class Prog:
    name: str
    ops: list
    inputs: tuple = ()
    commit: dict = field(default_factory=dict)
    outputs: dict = field(default_factory=dict)


def test_chain_cycles_exact():
    # mul issued at 0 writes at 0 + 1 + 5 = 6 (bypassed to a read in cycle 6); the add
    # issued at 6 writes at 6 + 1 + 8 = 15
    p = Prog("c", [Op("t1", "mul", ("x", "y")), Op("t2", "add", ("t1", "x"))],
             commit={"z": "t2"})
    sp = schedule_program(p, Units(mul=1, add=1), ["x", "y", "z"])
    assert [s.issue for s in sp.ops] == [0, 6]
    assert sp.cycles == 6 + 1 + UNIT_LATENCY["add"] + 1 == 16
    assert sp.direct == {"t2": "z"}


def test_resource_bound_exact():
    ops = [Op(f"t{i}", "mul", ("x", "y")) for i in range(5)]
    p = Prog("r", ops, outputs={f"o{i}": f"t{i}" for i in range(5)})
    sp = schedule_program(p, Units(mul=2, add=1), ["x", "y"])
    assert sorted(s.issue for s in sp.ops) == [0, 0, 1, 1, 2]
    assert sp.cycles == 2 + 1 + 5 + 1


def test_commit_needs_copy_when_target_read_late():
    # t1 = x * y is written at 6, but x is read again by an op issued at 6 or later
    ops = [Op("t1", "mul", ("x", "y")), Op("t2", "mul", ("t1", "y")),
           Op("t3", "add", ("t2", "x"))]
    p = Prog("m", ops, commit={"x": "t1", "w": "t3"})
    sp = schedule_program(p, Units(mul=1, add=1), ["x", "y", "w"])
    movs = [s for s in sp.ops if s.kind == "mov"]
    assert len(movs) == 1 and movs[0].dst == "x"
    t3 = next(s for s in sp.ops if s.dst == "t3")
    assert movs[0].issue + 1 + UNIT_LATENCY["mov"] > t3.issue  # after the last read of x


def test_unknown_operand_and_bad_neg_rejected():
    with pytest.raises(ScheduleError):
        schedule_program(Prog("u", [Op("t1", "mul", ("x", "q"))]), Units(), ["x"])
    p = Prog("n", [Op("t1", "neg", ("x",))], commit={"x": "t1"})
    with pytest.raises(ScheduleError):
        schedule_program(p, Units(), ["x"])


def _reference(prog, regs):
    vals = dict(regs)
    for op in prog.ops:
        get = [np.uint32(int(s[2:], 16)) if s.startswith("c:") else np.uint32(vals[s])
               for s in op.srcs]
        k = op.kind
        if k == "neg":
            r = F.fp32_neg(get[0])
        elif k == "sqrt":
            r = F.fp32_sqrt(get[0])
        elif k in ("le", "lt"):
            c = F.fp32_compare(get[0], get[1])
            flag = c["lt"] | c["eq"] if k == "le" else c["lt"]
            r = 0x3F800000 if flag else 0
        else:
            r = {"add": F.fp32_add, "sub": F.fp32_sub, "mul": F.fp32_mul,
                 "div": F.fp32_div}[k](get[0], get[1])
        vals[op.dst] = int(r)
    new = dict(regs)
    for reg, t in prog.commit.items():
        new[reg] = vals[t]
    return new, {k: vals[t] for k, t in prog.outputs.items()}


SPECIALS = [0x00000000, 0x80000000, 0x7F800000, 0xFF800000, 0x7FC00000, 0x00000001,
            0x807FFFFF, 0x7F7FFFFF, 0xFF7FFFFF, 0x00800000, 0x3F800000, 0xBF800000]


def _random_program(rng, n_regs=12, n_ops=120):
    regs = [f"r{i}" for i in range(n_regs)]
    avail = list(regs) + ["c:3f800000", "c:c0490fdb"]
    ops = []
    for i in range(n_ops):
        kind = rng.choice(["add", "sub", "mul", "mul", "div", "sqrt", "le", "lt", "neg"])
        a, b = rng.choice(avail), rng.choice(avail)
        srcs = (a,) if kind in ("sqrt", "neg") else (a, b)
        dst = f"t{i + 1}"
        ops.append(Op(dst, kind, srcs))
        avail.append(dst)
    producers = [o.dst for o in ops if o.kind != "neg"]
    commit = {r: producers[-1 - i] for i, r in enumerate(regs[:6])}
    outputs = {"o0": producers[-8], "o1": producers[len(producers) // 2]}
    return Prog("rand", ops, commit=commit, outputs=outputs), regs


@pytest.mark.parametrize("seed", [0, 1])
def test_random_program_bit_exact_amaranth(seed):
    rng = np.random.default_rng(seed)
    prog, regs = _random_program(rng)
    words = {}
    for r in regs:
        if rng.random() < 0.35:
            words[r] = int(rng.choice(SPECIALS))
        else:
            words[r] = int(np.float32(rng.normal() * 2.0 ** rng.integers(-20, 20))
                           .view(np.uint32))
    img = MachineImage.build({"rand": prog}, Units(mul=2, add=2), regs)
    init = {img.layout.fixed[r]: w for r, w in words.items()}
    dut = ScheduledMachine(img, init=init)
    exp_regs, exp_out = _reference(prog, words)
    got: dict = {}

    async def bench(ctx):
        ctx.set(dut.start, 1)
        await ctx.tick()
        ctx.set(dut.start, 0)
        n = 1
        while not ctx.get(dut.done):
            await ctx.tick()
            n += 1
        got["cycles"] = n
        for name, addr in list(img.layout.fixed.items()) + \
                [("out:" + k, a) for k, a in img.output_addr("rand").items()]:
            ctx.set(dut.host_raddr, addr)
            await ctx.tick()
            got[name] = ctx.get(dut.host_rdata)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert got["cycles"] == img.cycles("rand") + 1
    assert {r: got[r] for r in regs} == exp_regs
    assert {k: got["out:" + k] for k in exp_out} == exp_out
