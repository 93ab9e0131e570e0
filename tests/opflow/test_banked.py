"""The banked scheduled float32 datapath (navgate.opflow): exact cycle counts of
small programs, rejected programs, the port constraints of every schedule (one write and
``read_ports`` distinct reads per bank per cycle, one issue per slot, the iterative cores'
interval), and bit-exact execution of random programs with special values in Amaranth
simulation against navgate.numerics.fp32."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest
from amaranth.sim import Simulator

from navgate.numerics import fp32 as F
from navgate.opflow.loopmachine import run_to_done
from navgate.opflow.machine import BankedImage
from navgate.opflow.schedule import (
    OVERHEAD,
    UNIT_LATENCY,
    BankedUnits,
    ScheduleError,
    schedule_banked,
)


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




def _banks(names, units):
    return {n: k % units.banks for k, n in enumerate(names)}


def test_chain_cycles_exact_not_transparent():
    # mul issued at 0 writes at 0 + 2 + 5 = 7 (bank read, operand register, 5 stages); the
    # read is not transparent, so the add issues at 8 and writes at 8 + 2 + 8 = 18
    u = BankedUnits(mul=1, add=1)
    p = Prog("c", [Op("t1", "mul", ("x", "y")), Op("t2", "add", ("t1", "x"))],
             commit={"z": "t2"})
    sp = schedule_banked(p, u, _banks(["x", "y", "z"], u))
    assert OVERHEAD == 3
    assert [s.issue for s in sp.ops] == [0, UNIT_LATENCY["mul"] + 3]
    assert sp.cycles == 8 + 2 + UNIT_LATENCY["add"] + 1 == 19
    assert sp.direct == {"t2": "z"}  # placed in z's bank, written in place


def test_read_port_limit_delays_issue():
    # four products of four words all in one bank: with two read ports per bank only one
    # two-operand op per cycle can read it, whatever the number of multipliers
    u = BankedUnits(mul=4, add=1, read_ports=2)
    names = ["a", "b", "c", "d"]
    ops = [Op("t0", "mul", ("a", "b")), Op("t1", "mul", ("c", "d")),
           Op("t2", "mul", ("a", "c")), Op("t3", "mul", ("b", "d"))]
    p = Prog("r", ops, outputs={f"o{i}": f"t{i}" for i in range(4)})
    sp = schedule_banked(p, u, {n: 0 for n in names})
    assert sorted(s.issue for s in sp.ops) == [0, 1, 2, 3]
    # spread over four banks they issue together
    sp = schedule_banked(p, u, {n: k for k, n in enumerate(names)})
    assert sorted(s.issue for s in sp.ops) == [0, 0, 0, 0]
    # the same word read twice takes one port
    p2 = Prog("s", [Op("t0", "mul", ("a", "a")), Op("t1", "mul", ("a", "b"))],
              outputs={"o0": "t0", "o1": "t1"})
    sp = schedule_banked(p2, u, {"a": 0, "b": 0})
    assert sorted(s.issue for s in sp.ops) == [0, 0]


def test_iterative_core_interval_respected():
    # three independent divisions on the iterative divider: issued INTERVAL cycles apart
    u = BankedUnits(mul=1, add=1, iterative=True)
    ops = [Op(f"t{i}", "div", ("a", "b")) for i in range(3)]
    p = Prog("d", ops, outputs={f"o{i}": f"t{i}" for i in range(3)})
    sp = schedule_banked(p, u, {"a": 0, "b": 1})
    iv = u.interval("div")
    assert iv > 1 and sorted(s.issue for s in sp.ops) == [0, iv, 2 * iv]
    assert sp.cycles == 2 * iv + 2 + u.latency("div") + 1


def test_unknown_operand_rejected():
    u = BankedUnits()
    with pytest.raises(ScheduleError):
        schedule_banked(Prog("u", [Op("t1", "mul", ("x", "q"))]), u, {"x": 0})
    p = Prog("n", [Op("t1", "neg", ("x",))], commit={"x": "t1"})
    with pytest.raises(ScheduleError):  # a neg result committed (not an arithmetic use)
        schedule_banked(p, u, {"x": 0})
    with pytest.raises(ScheduleError):  # x * y with both in one single-ported bank
        schedule_banked(Prog("p", [Op("t1", "mul", ("x", "y"))], outputs={"o": "t1"}),
                        BankedUnits(read_ports=1), {"x": 0, "y": 0})


def _field(img, row, key):
    off, w = img.fields.pos[key]
    return img.rom[row] >> off & ((1 << w) - 1)


def _check_ports(img):
    """Every schedule within the ports (one issue per slot; per bank per cycle at most
    ``read_ports`` distinct words read and one written; with a shared port A, reads +
    writes <= 2), and the microcode: every operand of every op selects a bank port whose
    address field holds the operand's address in its issue row, never port 0 of a bank the
    row writes when port A is shared, and every write sets the bank's write enable and
    address in its write row."""
    u = img.units
    lb = img.layout.local_bits
    for key, sp in img.programs.items():
        base = img.base[key]
        addr = dict(img.layout.fixed)
        addr.update(img.layout.temp_addr[key])
        reads: dict = {}
        writes: dict = {}
        issues: set = set()
        for s in sp.ops:
            slot = u.slot_of(s.unit if s.unit in ("mul", "add") else "misc", s.inst)
            assert (s.issue, slot) not in issues
            issues.add((s.issue, slot))
            for name, _ in s.srcs:
                reads.setdefault((s.issue, addr[name] >> lb), set()).add(addr[name])
            dst = img.layout.fixed[s.dst] if s.kind == "mov" else addr.get(s.dst)
            if dst is not None:
                k = (s.write, dst >> lb)
                writes[k] = writes.get(k, 0) + 1
                row = base + s.write
                assert _field(img, row, ("we", dst >> lb)) == 1
                assert _field(img, row, img.fields.wa(dst >> lb)) == dst & ((1 << lb) - 1)
        assert max(len(v) for v in reads.values()) <= u.read_ports
        assert max(writes.values()) == 1
        for k, v in reads.items():
            if u.shared(k[1]):
                assert len(v) + writes.get(k, 0) <= 2, (key, k)
        port_words: dict = {}
        for s in sp.ops:
            slot = u.slot_of(s.unit if s.unit in ("mul", "add") else "misc", s.inst)
            row = base + s.issue
            for j, (name, _) in enumerate(s.srcs):
                sel = _field(img, row, ("sel", slot, j))
                if u.split_ports:  # operand port j reads read port j of bank ``sel``
                    b, port = sel, j
                    port_words.setdefault((s.issue, b, port), set()).add(addr[name])
                else:
                    b, port = divmod(sel, u.read_ports)
                assert addr[name] >> lb == b
                assert _field(img, row, ("ra", b, port)) == addr[name] & ((1 << lb) - 1)
                if u.shared(b) and port == 0:
                    assert _field(img, row, ("we", b)) == 0, (key, s.issue, b)
        assert all(len(v) == 1 for v in port_words.values())  # one word per split port


def test_split_ports_swap_commutative_ops():
    # a in bank 0, b and c in bank 1. t0 = a * b takes port 0 of bank 0 (a) and port 1 of
    # bank 1 (b). Split ports: a * c cannot read c on port 1 of bank 1 in cycle 0, but
    # swapped (c on port 0, a on port 1) it issues with t0; a / c cannot swap and waits a
    # cycle; a - c issues in cycle 0 as (-c) + a. Shared ports: all in cycle 0.
    bank = {"a": 0, "b": 1, "c": 1}
    for kind, cycle in (("mul", 0), ("sub", 0), ("div", 1)):
        p = Prog("w", [Op("t0", "mul", ("a", "b")), Op("t1", kind, ("a", "c"))],
                 outputs={"o0": "t0", "o1": "t1"})
        sp = schedule_banked(p, BankedUnits(mul=2, add=1, split_ports=True), bank)
        t1 = next(s for s in sp.ops if s.dst == "t1")
        assert t1.issue == cycle, kind
        if kind == "mul":
            assert t1.srcs == (("c", False), ("a", False))
        if kind == "sub":
            assert (t1.kind, t1.srcs) == ("add", (("c", True), ("a", False)))
        if kind == "div":
            assert (t1.kind, t1.srcs) == ("div", (("a", False), ("c", False)))
        sp = schedule_banked(p, BankedUnits(mul=2, add=1), bank)
        assert [s.issue for s in sp.ops if s.dst in ("t0", "t1")] == [0, 0]
    # the same word on both ports of one op, and a third op sharing both ports
    p = Prog("q", [Op("t0", "mul", ("b", "b")), Op("t1", "mul", ("b", "b")),
                   Op("t2", "mul", ("c", "b"))], outputs={f"o{i}": f"t{i}" for i in range(3)})
    sp = schedule_banked(p, BankedUnits(mul=3, add=1, split_ports=True), bank)
    assert sorted(s.issue for s in sp.ops) == [0, 0, 1]
    with pytest.raises(ScheduleError):
        schedule_banked(p, BankedUnits(split_ports=True, shared_write_port=True), bank)


def test_shared_write_port_limits():
    # twelve products, each of two words of bank 0 (24 distinct words): one per cycle on
    # the single multiplier. Separate write port: issues 0..11 back to back. True-dual-port
    # banks (shared_write_port): the results are written from cycle 7 on, into bank 0 (the
    # multiplier's own bank) while its port is free there; a cycle that writes bank 0
    # leaves it one read port, so no product issues in a cycle that writes bank 0
    words = [f"w{i}" for i in range(24)]
    ops = [Op(f"t{i}", "mul", (words[2 * i], words[2 * i + 1])) for i in range(12)]
    p = Prog("s", ops, outputs={f"o{i}": f"t{i}" for i in range(12)})
    bank = {w: 0 for w in words}
    sp = schedule_banked(p, BankedUnits(mul=1, add=1), bank)
    assert sorted(s.issue for s in sp.ops) == list(range(12))
    sp = schedule_banked(p, BankedUnits(mul=1, add=1, shared_write_port=True), bank)
    written = {(s.write, s.bank) for s in sp.ops}
    assert any(b == 0 for _, b in written)
    assert all((s.issue, 0) not in written for s in sp.ops)
    assert sorted(s.issue for s in sp.ops)[:7] == list(range(7))
    assert max(s.issue for s in sp.ops) > 11
    # only bank 0 true-dual-port: the results go to bank 1 (a write costs a shared bank a
    # read port), and the products issue back to back again
    sp = schedule_banked(p, BankedUnits(mul=1, add=1, shared_write_port=(0,)), bank)
    assert sorted(s.issue for s in sp.ops) == list(range(12))
    assert {s.bank for s in sp.ops} == {1}
    with pytest.raises(ScheduleError):  # a true-dual-port bank has two ports
        schedule_banked(p, BankedUnits(read_ports=3, shared_write_port=True), bank)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4, 5, 6, 7])
def test_random_program_bit_exact_amaranth(seed):
    rng = np.random.default_rng(seed)
    prog, regs = _random_program(rng, n_ops=160)
    words = {}
    for r in regs:
        if rng.random() < 0.35:
            words[r] = int(rng.choice(SPECIALS))
        else:
            words[r] = int(np.float32(rng.normal() * 2.0 ** rng.integers(-20, 20))
                           .view(np.uint32))
    # seeds 4 and 5: true-dual-port banks (shared write port / read port 0), all banks or
    # two of them; seeds 6 and 7: split read ports (swapped commutative ops)
    units = BankedUnits(mul=2, add=2, read_ports=2 + (seed % 2 if seed < 4 else 0),
                        misc_bank=seed not in (3, 5, 7), iterative=seed in (3, 5, 7),
                        shared_write_port={4: True, 5: (0, 2)}.get(seed, False),
                        split_ports=seed >= 6)
    img = BankedImage.build({"rand": prog}, units, regs)
    _check_ports(img)
    if units.split_ports:  # some sources were swapped (a sub became an add)
        kinds = {op.dst: op.kind for op in prog.ops}
        swapped = [s for s in img.programs["rand"].ops if s.kind != "mov"
                   and (s.kind != kinds[s.dst] or s.srcs[0][0] != _src0(prog, s.dst))]
        assert swapped
    init = {img.layout.fixed[r]: w for r, w in words.items()}
    dut = img.machine(init)
    exp_regs, exp_out = _reference(prog, words)
    got: dict = {}

    async def bench(ctx):
        got["cycles"] = await run_to_done(ctx, dut, 10 * img.cycles("rand") + 100)
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


def _src0(prog, dst):
    """The first source of ``dst``'s op, through negs (as the scheduler folds them)."""
    ops = {op.dst: op for op in prog.ops}
    name = ops[dst].srcs[0]
    while name in ops and ops[name].kind == "neg":
        name = ops[name].srcs[0]
    return name


def test_engine_image_respects_ports():
    from navgate.systems.ins_trn.pl.nav_engines import engine_image

    _check_ports(engine_image("ins_engines"))


def test_engine_image_shared_write_port_respects_ports():
    from dataclasses import replace

    from navgate.systems.ins_trn.pl.nav_engines import ENGINE_UNITS, engine_image

    base = replace(ENGINE_UNITS, split_ports=False)  # operand ports not split (§7's runs)
    img = engine_image("ins_engines", replace(base, shared_write_port=True))
    _check_ports(img)
    # one address field per bank fewer: 8 banks x 8 bits
    assert img.fields.width == engine_image("ins_engines", base).fields.width - 8 * 8
    # exact cycles (docs/seed000-engines.md §7): every bank true-dual-port is port-bound
    # (2-D update 142 + 1 + 325 + 1 = 469 > 450); bank 0 alone keeps it at 420
    assert {k: img.cycles(k) for k in img.programs} == {
        "propagate": 782, "alt_gate": 55, "alt_apply": 245, "trn_gate": 142,
        "trn_apply": 325}
    one = engine_image("ins_engines", replace(base, shared_write_port=(0,)))
    _check_ports(one)
    assert {k: one.cycles(k) for k in one.programs} == {
        "propagate": 659, "alt_gate": 55, "alt_apply": 234, "trn_gate": 142,
        "trn_apply": 276}
    assert one.fields.width == img.fields.width + 7 * 8
