"""opflow.execute: the compiled machine against the bit-true interpreter (numerics.fp32) op
by op on random programs with special values, the underflow rule, and the register file built
from the programs' own named registers."""

import numpy as np
import pytest

from navgate.numerics import fp32 as F
from navgate.numerics.fp32 import float_to_bits, floats_to_bits
from navgate.opflow import ir
from navgate.opflow.execute import (
    Machine,
    commit,
    execute,
    run_bittrue,
)

SPECIAL = np.array([0x00000000, 0x80000000, 0x3F800000, 0xBF800000, 0x7F800000, 0xFF800000,
                    0x7FC00000, 0x00800000, 0x80800000, 0x00800001, 0x7F7FFFFF, 0xFF7FFFFF,
                    0x1F800000, 0x20000000, 0x5F800000, 0x3F800001, 0x3F7FFFFF, 0x00FFFFFF],
                   dtype=np.uint32)


def _random_bits(rng, n):
    """Normal float32 patterns over a wide exponent range, plus special values."""
    sign = rng.integers(0, 2, n, dtype=np.uint32) << np.uint32(31)
    exp = rng.integers(1, 255, n, dtype=np.uint32)
    narrow = rng.random(n) < 0.6  # many operands near 1: cancellation and exact results
    exp[narrow] = rng.integers(110, 145, narrow.sum(), dtype=np.uint32)
    frac = rng.integers(0, 1 << 23, n, dtype=np.uint32)
    bits = sign | (exp << np.uint32(23)) | frac
    pick = rng.random(n) < 0.15
    bits[pick] = rng.choice(SPECIAL, pick.sum())
    return bits


def _random_program(rng, n_regs, n_ops):
    prog = ir.Program("random")
    names = [f"r{i}" for i in range(n_regs)]
    kinds = ["add", "sub", "mul", "div", "sqrt", "neg", "le", "lt"]
    for i in range(n_ops):
        k = kinds[rng.integers(len(kinds))]
        srcs = tuple(names[rng.integers(len(names))] for _ in range(1 if k in ("sqrt", "neg")
                                                                     else 2))
        dst = f"t{i + 1}"
        prog.ops.append(ir.Op(dst, k, srcs, "random"))
        names.append(dst)
    prog.inputs = tuple(f"r{i}" for i in range(n_regs))
    return prog


def test_compiled_machine_matches_numerics_fp32_op_by_op_on_random_programs():
    rng = np.random.default_rng(2026)
    n_regs, n_ops, lanes = 24, 600, 48
    prog = _random_program(rng, n_regs, n_ops)
    init = {f"r{i}": F.flush_subnormal(_random_bits(rng, lanes)) for i in range(n_regs)}
    _, _, want = run_bittrue(prog, {}, init, lanes)
    m = Machine({"p": prog})
    c = m.compiled["p"]
    checked = 0
    for lane in range(lanes):
        for name, bits in init.items():
            m.regs[m.index[name]] = float(np.uint32(bits[lane]).view(np.float32))
        execute(m.regs, c.ops)
        for op in prog.ops:
            got = float_to_bits(m.regs[_temp_index(m, "p", op.dst)])
            assert got == int(want[op.dst][lane]), (lane, op, hex(got),
                                                     hex(int(want[op.dst][lane])))
            checked += 1
    assert checked == lanes * n_ops


def _temp_index(machine, key, dst):
    prog = machine.compiled[key].prog
    return machine.compiled[key].ops[[op.dst for op in prog.ops].index(dst), 1]


def test_underflow_boundary_follows_the_fp32_rule():
    """Products just below 2^-126 (case 3 of numerics.fp32): zero or 2^-126 exactly as the
    specification rounds, which IEEE float32 with gradual underflow does not."""
    prog = ir.Program("uf", [ir.Op("t1", "mul", ("a", "b"), "uf")], inputs=("a", "b"))
    m = Machine({"p": prog})
    a = np.float32(1.0 - 2.0**-24)  # 0x3F7FFFFF
    for b_bits in (0x00800000, 0x00800001, 0x00800002):
        b = np.uint32(b_bits).view(np.float32)
        m.regs[m.index["a"]] = float(a)
        m.regs[m.index["b"]] = float(b)
        execute(m.regs, m.compiled["p"].ops)
        want = F.fp32_mul(np.uint32(a.view(np.uint32)), np.uint32(b_bits))
        assert float_to_bits(m.regs[m.compiled["p"].ops[0, 1]]) == int(want)




def _accumulator(name, registers, gain):
    """``acc <- acc * gain + x`` and output ``y = acc * gain``, with named registers."""
    b = ir.Builder(name, ("x",), registers=registers)
    new = b.add(b.mul("acc", gain), "x")
    b.prog.outputs = {"y": b.mul("acc", gain)}
    b.prog.commit = {"acc": new}
    return b.prog


def test_register_file_is_the_programs_named_registers():
    """Named registers are the union of the programs' ``registers`` in order, first; inputs
    and constants follow; temporaries share the slots above; state persists across runs and
    programs, the commit is read from temporaries computed before it."""
    p1 = _accumulator("a", ("acc", "k"), 0.5)
    p2 = _accumulator("b", ("acc", "other"), 3.0)
    m = Machine({"a": p1, "b": p2})
    assert m.registers == ("acc", "k", "other")
    assert [m.index[n] for n in m.registers] == [0, 1, 2]
    assert m.index["x"] == 3
    assert set(m.bits()) == {"acc", "k", "other"}
    base = len(m.index)
    assert m.regs.shape == (base + max(len(p1.ops), len(p2.ops)),)
    m.set("acc", 1.0)
    assert m.run("a", x=2.0) == {"y": 0.5}
    assert m.get("acc") == 2.5
    assert m.run("b", x=0.1) == {"y": 7.5}
    assert m.get("acc") == float(np.float32(np.float32(7.5) + np.float32(0.1)))
    assert m.bits()["acc"] == int(F.fp32_add(F.f32_to_bits(7.5), F.f32_to_bits(0.1)))
    with pytest.raises(KeyError):
        m.run("a", nope=1.0)


def test_commit_copies_in_table_order():
    prog = ir.Program("swap", [ir.Op("t1", "neg", ("u",), "s"), ir.Op("t2", "neg", ("v",), "s")],
                      commit={"u": "t2", "v": "t1"}, registers=("u", "v"))
    m = Machine({"s": prog})
    m.set("u", 1.5)
    m.set("v", -2.0)
    c = m.compiled["s"]
    execute(m.regs, c.ops)
    commit(m.regs, c.table)
    assert (m.get("u"), m.get("v")) == (2.0, -1.5)
    assert list(floats_to_bits([m.get("u"), np.nan])) == [0x40000000, F.QNAN]
