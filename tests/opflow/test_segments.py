"""Straight-line programs as one-iteration loop nests (navgate.opflow.segments): the nest run
by the loop executor gives the bit-true interpreter's committed registers and outputs on
random programs with special values; reads see the values at program start; ``cvt`` of a
word is the word (done at the boundary); dead ops are left out; the nest runs on the
sequence machine in Amaranth's simulator with the schedule's cycles; bad layouts are
rejected."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.numerics.fp32 import float_to_bits, floats_to_bits
from navgate.opflow.execute import run_bittrue
from navgate.opflow.ir import Builder
from navgate.opflow.loops import LoopError, run_nest
from navgate.opflow.segments import named_reads, program_arrays, segment_nest
from navgate.opflow.sequence import SequenceProgram, schedule_sequence, simulate_sequence

SPECIAL = [0.0, -0.0, float("inf"), float("-inf"), float("nan"), 1e-45, 3e38, -1.5]


def random_program(rng, n_ops=60, regs=6, ins=3):
    names = [f"r{k}" for k in range(regs)]
    inputs = [f"i{k}" for k in range(ins)]
    b = Builder("rand", inputs, registers=names)
    pool = names + inputs + [b.c(0.5), b.c(-2.0)]
    for _ in range(n_ops):
        kind = rng.choice(["add", "sub", "mul", "div", "sqrt", "neg", "lt", "le", "cvt"])
        a, c = (pool[int(k)] for k in rng.integers(0, len(pool), 2))
        pool.append(getattr(b, kind)(a) if kind in ("sqrt", "neg", "cvt")
                    else getattr(b, kind)(a, c))
    temps = pool[len(names) + len(inputs) + 2:]
    for k, r in enumerate(names[:4]):  # commits (one a copy of another register)
        b.prog.commit[r] = temps[-1 - k] if k < 3 else names[5]
    b.prog.outputs = {"o0": temps[-5], "o1": temps[len(temps) // 2], "o2": inputs[0]}
    return b.prog


def layout(prog):
    words = program_arrays(named_reads(prog) + list(prog.registers) + list(prog.inputs),
                           lambda n: "IN" if n.startswith("i") else "S")
    places = {n: (a, w) for a, ws in words.items() for n, w in ws.items()}
    arrays = {a: len(ws) for a, ws in words.items()} | {"OUT": 3}
    return places, arrays, {f"o{k}": ("OUT", k) for k in range(3)}


def run_both(prog, rng, special):
    places, arrays, writes = layout(prog)
    nest = segment_nest(prog, places, arrays, writes)
    vals = {n: (float(rng.choice(SPECIAL)) if special and rng.random() < 0.3
                else float(rng.uniform(-4, 4))) for n in places}
    for n in prog.inputs:  # cvt reads the float32 of a number: integers here
        vals[n] = float(int(vals[n] * 1000)) if abs(vals[n]) < 1e6 else vals[n]
    for n, v in vals.items():  # memories hold flushed words (a subnormal reads as zero)
        vals[n] = v * 0.0 if v != 0 and abs(v) < 2.0**-126 else v
    mems = {a: np.zeros(w) for a, w in arrays.items()}
    for n, (a, w) in places.items():
        mems[a][w] = vals[n]
    got = run_nest(nest, mems)
    state = {n: floats_to_bits([vals[n]])[0] for n in prog.registers}
    # as registers (bit patterns): cvt of a float32 word is the word
    inputs = {n: floats_to_bits([vals[n]])[0] for n in prog.inputs}
    new, outs, _ = run_bittrue(prog, state, inputs)
    for r in prog.commit:
        a, w = places[r]
        assert float_to_bits(got[a][w]) == int(new[r][0]), r
    for k, (a, w) in writes.items():
        assert float_to_bits(got[a][w]) == int(outs[k][0]), k
    return nest, mems, got


@pytest.mark.parametrize("special", [False, True])
def test_segment_nest_equals_the_bittrue_interpreter(special):
    rng = np.random.default_rng(3 + special)
    for _ in range(15):
        run_both(random_program(rng), rng, special)


def test_reads_see_program_start_and_dead_ops_are_dropped():
    b = Builder("swap", (), registers=("x", "y"))
    s = b.add("x", "y")
    b.mul("x", "x")  # dead
    b.prog.commit = {"x": "y", "y": s}
    nest = segment_nest(b.prog, {"x": ("S", 0), "y": ("S", 1)}, {"S": 2})
    assert [op.kind for op in nest.ops] == ["load", "load", "add"]
    got = run_nest(nest, {"S": np.array([1.5, 2.25])})["S"]
    assert list(got) == [2.25, 3.75]


def test_cvt_is_the_boundary_word():
    b = Builder("c", ("w",), registers=("x",))
    b.prog.commit = {"x": b.mul(b.cvt("w"), 0.5)}
    nest = segment_nest(b.prog, {"w": ("IN", 0), "x": ("S", 0)}, {"IN": 1, "S": 1})
    assert all(op.kind != "cvt" for op in nest.ops)
    assert run_nest(nest, {"IN": np.array([-32768.0]), "S": np.zeros(1)})["S"][0] == -16384.0


def test_bad_layouts_are_rejected():
    b = Builder("bad", ("w",), registers=("x",))
    b.prog.commit = {"x": b.add("x", "w")}
    with pytest.raises(LoopError, match="'w' has no place"):
        segment_nest(b.prog, {"x": ("S", 0)}, {"S": 1})
    with pytest.raises(LoopError, match="commit x has no place"):
        segment_nest(b.prog, {"w": ("IN", 0)}, {"IN": 1})
    with pytest.raises(LoopError, match="not among the arrays"):
        segment_nest(b.prog, {"x": ("S", 0), "w": ("IN", 0)}, {"S": 1})
    with pytest.raises(LoopError, match="no output"):
        segment_nest(b.prog, {"x": ("S", 0), "w": ("IN", 0)}, {"S": 1, "IN": 1},
                     {"nope": ("S", 0)})
    b2 = Builder("k", (), registers=("x",))
    b2.prog.commit = {"x": b2.c(1.0)}
    with pytest.raises(LoopError, match="constant"):
        segment_nest(b2.prog, {"x": ("S", 0)}, {"S": 1})
    with pytest.raises(LoopError, match="out of range"):
        segment_nest(b.prog, {"x": ("S", 3), "w": ("IN", 0)}, {"S": 1, "IN": 1})


def test_segment_on_the_sequence_machine():
    """Two segments of random programs in one entry on the sequence machine (2 lanes):
    the executor's words, the schedule's cycles."""
    rng = np.random.default_rng(11)
    prog = random_program(rng, n_ops=30)
    places, arrays, writes = layout(prog)
    nest = segment_nest(prog, places, arrays, writes)
    prog2 = random_program(rng, n_ops=20)
    prog2.name = "rand2"
    nest2 = segment_nest(prog2, places, arrays, writes, name="rand2")
    sp = SequenceProgram("segs", arrays, {"a": nest, "b": nest2}, {"ab": ("a", "b")})
    sch = schedule_sequence(sp, 2)
    mems = {a: rng.uniform(-3, 3, w) for a, w in arrays.items()}
    from navgate.opflow.sequence import run_sequence
    want = run_sequence(sp, mems, "ab")
    (got, cycles), = simulate_sequence(sch, mems, ["ab"])
    assert cycles == sch.cycles("ab") == sch.schedules["a"].cycles + sch.schedules["b"].cycles + 1
    for a in arrays:
        assert list(got[a]) == list(floats_to_bits(want[a])), a
