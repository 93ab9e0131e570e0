"""The op-program IR (navgate.opflow.ir): named registers are the program's own, constants are
float32 bit patterns with subnormals flushed, the builder emits SSA temporaries."""

import numpy as np

from navgate.opflow.ir import Builder, Program, const_name, const_value


def test_registers_are_a_field_of_the_program():
    b = Builder("p", inputs=("x",), registers=("s0", "s1"))
    t = b.add(b.mul("x", "s0"), 2.0)
    b.prog.commit = {"s1": t}
    prog = b.prog
    assert prog.registers == ("s0", "s1")
    assert prog.names() == ["s0", "s1", "x", "t1", "c:40000000", "t2"]
    # another program keeps its own list: no global state list leaks in
    assert Builder("q", inputs=("y",)).prog.names() == ["y"]
    assert Program("r").registers == ()


def test_builder_emits_ssa_and_counts():
    b = Builder("p", inputs=("a", "b"))
    s = b.sum([(-1, "a"), (1, "b"), (-1, "a")])
    ops = b.prog.ops
    assert [op.kind for op in ops] == ["neg", "add", "sub"]
    assert len({op.dst for op in ops}) == len(ops) and ops[-1].dst == s
    assert b.prog.counts()["add"] == 1 and b.prog.counts()["neg"] == 1


def test_a_clients_own_kinds_and_named_results():
    """Builder.op takes any kind (a client's unit) and a result name; counts list the
    client's kinds after the float32 ones, by module too."""
    b = Builder("p", inputs=("a",))
    t = b.op("twice", "a", 1.0)
    b.module = "m2"
    out = b.op("add", t, "a", name="out")
    assert out == "out" and t == "t1"
    assert [(op.dst, op.kind, op.srcs) for op in b.prog.ops] == [
        ("t1", "twice", ("a", "c:3f800000")), ("out", "add", ("t1", "a"))]
    counts = b.prog.counts()
    assert counts["twice"] == 1 and counts["add"] == 1 and list(counts)[-1] == "twice"
    assert b.prog.counts_by_module()["p"]["twice"] == 1
    assert b.prog.counts_by_module()["m2"]["add"] == 1


def test_constants_are_float32_bits_with_subnormals_flushed():
    assert const_name(1.0) == "c:3f800000"
    assert const_name(-0.1) == f"c:{int(np.float32(-0.1).view(np.uint32)):08x}"
    assert const_name(1e-40) == "c:00000000"  # subnormal -> +0
    assert const_name(-1e-40) == "c:80000000"  # keeps its sign
    assert const_value("c:3f800000") == 1.0
    assert const_value(const_name(0.1)) == float(np.float32(0.1))
