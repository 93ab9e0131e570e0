"""Sequences of loop nests (navgate.opflow.sequence) and the new loop-body kinds (div, sqrt,
neg, lt, le): the executor against the bit-true interpreter and numpy float32, the modulo
scheduler with the non-pipelined iterative units, and the sequence machine in Amaranth's
simulator, bit-exact against the executor with exact cycle counts, at 1 and 2 lanes."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.gateware.fp32 import Fp32Add, Fp32Compare, Fp32DivIter, Fp32Mul, Fp32SqrtIter
from navgate.numerics.fp32 import floats_to_bits
from navgate.opflow import loop_kernels as K
from navgate.opflow.execute import run_bittrue
from navgate.opflow.loopmachine import LoopMachine
from navgate.opflow.loops import (
    Addr,
    LoopError,
    LoopNest,
    LoopUnits,
    LOp,
    Store,
    modulo_schedule,
    run_nest,
    unroll,
)
from navgate.opflow.sequence import (
    SequenceProgram,
    run_sequence,
    schedule_sequence,
    simulate_sequence,
)

from .conftest import SPECIAL, memories

ROWS, COLS = [0, 0, 2, 2, 2, 3, 5, 5], [1, 4, 0, 2, 3, 4, 0, 5]
DIV_I, SQRT_I = Fp32DivIter.INTERVAL, Fp32SqrtIter.INTERVAL


def new_kind_nests():
    return [K.scalar_div_sqrt(), K.diag_compare(5), K.vector_sqrt_div(4),
            K.sym_rank1_update_loaded(4)]


@pytest.mark.parametrize("special", [False, True])
def test_new_kinds_executor_equals_bittrue_interpreter(special):
    rng = np.random.default_rng(21 + special)
    for nest in new_kind_nests():
        for _ in range(4):
            mems = memories(nest, rng, special)
            got = run_nest(nest, mems)
            prog, regs = unroll(nest)
            state = {r: floats_to_bits([mems[a][i]])[0] for r, (a, i) in regs.items()}
            new, _, _ = run_bittrue(prog, state, {})
            for r, (a, i) in regs.items():
                assert int(new[r][0]) == int(floats_to_bits([got[a][i]])[0]), (nest.name, r)


def test_new_kinds_against_numpy_float32():
    f = np.float32
    got = run_nest(K.scalar_div_sqrt(), {"s": np.array([3.0, 7.0, 2.0, 0, 0, 0])})["s"]
    q, r = f(3.0) / f(7.0), np.sqrt(f(2.0))
    assert np.array_equal(floats_to_bits(got[3:]), floats_to_bits([-q * r, -r, q + r]))
    # directed: x/0 = -inf (sign of x), sqrt(-0) = -0 (its negation +0), sqrt(-1) = NaN,
    # a subnormal dividend is flushed to zero
    got = run_nest(K.scalar_div_sqrt(), {"s": np.array([-1.0, 0.0, -0.0, 0, 0, 0])})["s"]
    assert np.isnan(got[3])  # q = -inf, r = -0: (-q) r = inf * -0 = NaN
    assert got[4] == 0.0 and not np.signbit(got[4]) and got[5] == -np.inf
    got = run_nest(K.scalar_div_sqrt(), {"s": np.array([1e-40, 2.0, -4.0, 0, 0, 0])})["s"]
    assert np.isnan(got[3]) and np.isnan(got[4]) and np.isnan(got[5])
    got = run_nest(K.scalar_div_sqrt(), {"s": np.array([1e-40, 2.0, 4.0, 0, 0, 0])})["s"]
    assert got[3] == 0.0 and np.signbit(got[3]) and got[4] == -2.0 and got[5] == 2.0
    nest = K.diag_compare(3)
    p = np.array([1.0, 9, 9, 2.0, 9, np.nan])  # diagonal 1, 2, NaN
    got = run_nest(nest, {"P": p, "y": np.array([2.0, -2.0, 0.0]), "c": np.zeros(6)})["c"]
    # 1 < 2, not 2 < -2, NaN unordered; -2 <= 1, 2 <= 2, NaN unordered
    assert list(got) == [1.0, 0.0, 0.0, 1.0, 1.0, 0.0]


def test_scheduler_blocks_the_iterative_units_for_their_interval():
    s = modulo_schedule(K.vector_sqrt_div(5))
    assert (s.ii, s.res_mii) == (DIV_I, DIV_I)  # one divide per iteration: II = interval
    assert s.depth == 1 + 1 + Fp32SqrtIter.LATENCY + Fp32DivIter.LATENCY + 1
    assert s.cycles == 4 * DIV_I + s.depth
    # a straight line is list-scheduled: div and sqrt overlap on their own units, II = depth
    s = modulo_schedule(K.scalar_div_sqrt())
    assert s.ii == s.depth == s.cycles
    assert s.time["q"] == 2 and s.time["r"] == 3  # the second load port serves z a cycle late
    assert s.time["g"] == s.ready["q"] == 2 + Fp32DivIter.LATENCY  # neg costs nothing
    # two divides per iteration on the one divider: ResMII counts both intervals
    nest = K.vector_sqrt_div(3)
    two = LoopNest(nest.name + "_2", nest.trips, nest.arrays, {},
                   nest.ops + [LOp("q2", "div", ("q", "v"))], [],
                   [Store("z", nest.stores[0].addr, "q2")])
    s = modulo_schedule(two)
    assert (s.ii, s.res_mii) == (2 * DIV_I, 2 * DIV_I)
    assert s.time["q2"] >= s.time["q"] + DIV_I  # the divider is busy for its interval
    assert modulo_schedule(two, LoopUnits(div=2)).ii == DIV_I
    # compare: pipelined, latency of Fp32Compare
    s = modulo_schedule(K.diag_compare(4))
    assert s.ready["a"] == s.time["a"] + Fp32Compare.LATENCY
    assert LoopUnits().latency("mul") == Fp32Mul.LATENCY
    assert LoopUnits().occupancy("add") == 1 and LoopUnits().occupancy("sqrt") == SQRT_I


def _critical_path_nest():
    """Straight line, program order against the critical path: three short products, then
    a chain of three squarings of ``a[3]``; every result stored to ``o``."""
    ops = [LOp("x1", "load", ("a",), Addr(None, (), 1)),
           LOp("x2", "load", ("a",), Addr(None, (), 2)),
           LOp("x3", "load", ("a",), Addr(None, (), 3)),
           LOp("s1", "mul", ("x2", "x3")), LOp("s2", "mul", ("x1", "x3")),
           LOp("s3", "mul", ("x1", "x2")), LOp("c1", "mul", ("x3", "x3")),
           LOp("c2", "mul", ("c1", "c1")), LOp("c3", "mul", ("c2", "c2"))]
    return LoopNest("cp_order", (), {"a": 4, "o": 4}, {}, ops, [],
                    [Store("o", Addr(None, (), k), s)
                     for k, s in enumerate(("s1", "s2", "s3", "c3"))])


@pytest.mark.parametrize("registered", [False, True])
def test_straight_line_is_list_scheduled_by_critical_path(registered):
    """One multiplier, two read ports: the chain's load and first product go first (the
    longest path to the end), the short products fill the chain's latency; in program
    order (the modulo scheduler's greedy placement) the chain would start behind them."""
    from navgate.opflow.loops import _place

    nest = _critical_path_nest()
    # then, back to back: o[3] (written in seg's last cycle) read at offset 1, doubled
    twice = LoopNest("twice", (), nest.arrays, {}, [
        LOp("w", "load", ("o",), Addr(None, (), 3)), LOp("d", "add", ("w", "w"))], [],
        [Store("a", Addr(None, (), 0), "d")])
    prog = SequenceProgram("cp", nest.arrays, {"seg": nest, "twice": twice},
                           {"run": ("seg",), "both": ("seg", "twice")})
    sch = schedule_sequence(prog, 1, registered=registered)
    s = sch.schedules["seg"]
    ld, mul = s.units.latency("load"), s.units.latency("mul")
    # cycle 1: x3 and x2 (the highest), x1 at 2; c1 as soon as x3 is ready, then s1..s3
    # one a cycle, c2 and c3 each a multiply latency after the one before; c3's store
    assert s.time["x3"] == s.time["x2"] == 1 and s.time["x1"] == 2
    assert s.time["c1"] == 1 + ld
    assert [s.time[k] for k in ("s1", "s2", "s3")] == [2 + ld, 3 + ld, 4 + ld]
    assert s.time["c3"] == 1 + ld + 2 * mul
    assert s.ii == s.depth == 1 + ld + 3 * mul + 1
    greedy = _place(nest, s.units, 1000, {})[3]
    # greedy: x1, x2 at 1, x3 at 2; s3, s1, s2 from 1 + ld; c1 behind them at 4 + ld
    assert greedy == 4 + ld + 3 * mul + 1 > s.depth
    rng = np.random.default_rng(3)
    mems = {"a": rng.standard_normal(4), "o": np.zeros(4)}
    t = sch.schedules["twice"]
    assert t.time["w"] == 1
    runs = simulate_sequence(sch, mems, ["run", ("both", mems)])
    for entry, (words, cycles), n in zip(("run", "both"), runs, (s.depth + 1,
                                                              s.depth + t.depth + 1),
                                         strict=True):
        want = run_sequence(prog, mems, entry)
        assert cycles == sch.cycles(entry) == n, entry
        for name in prog.arrays:
            assert np.array_equal(words[name], floats_to_bits(want[name])), (entry, name)


def _chain_memories(prog, rng, special=False):
    mems = {}
    for name, words in prog.arrays.items():
        v = rng.standard_normal(words) * np.exp(rng.uniform(-3, 3, words))
        if special:
            v = rng.choice(SPECIAL, words)
        v = v.astype(np.float32).astype(np.float64)
        v[np.abs(v) < 2.0**-126] *= 0.0
        mems[name] = v
    mems["x"] = np.abs(mems["x"])
    return mems


@pytest.mark.parametrize("lanes, registered", [(1, True), (2, True), (1, False)])
def test_sequence_machine_bit_exact_with_exact_cycles(lanes, registered):
    """Entries run one after another on the same memories: all (scalar div/sqrt -> sparse
    mat-vec -> rank-1 update with the scalar -> compares), update, norm (sqrt/div per
    iteration), then prep again on directed edge cases written between runs."""
    prog = K.chain_program(6, ROWS, COLS)
    sch = schedule_sequence(prog, lanes, registered=registered)
    rank1 = sch.schedules["rank1"]
    assert rank1.ii == (2 if lanes == 1 else 1)  # two multiplies per stored element
    assert sch.schedules["spmv"].ii == Fp32Add.LATENCY + registered  # the recurrence
    assert sch.schedules["norm"].ii == DIV_I
    rng = np.random.default_rng(5 + lanes)
    mems = _chain_memories(prog, rng)
    edge = [np.array([-1.0, 0.0, -0.0, 0, 0, 0]), np.array([1e-40, 2.0, -4.0, 0, 0, 0]),
            np.array([np.inf, np.inf, np.inf, 0, 0, 0])]
    runs = [("all", None), ("update", None), ("norm", None)] + [("prep", {"s": e})
                                                               for e in edge]
    got = simulate_sequence(sch, mems, runs)
    want = mems
    for (entry, write), (words, cycles) in zip(runs, got, strict=True):
        if write:
            want = {**want, **write}
        want = run_sequence(prog, want, entry)
        assert cycles == sch.cycles(entry), entry
        for name in prog.arrays:
            assert np.array_equal(words[name], floats_to_bits(want[name])), (entry, name)
    # segments back to back: cmp issues in the cycle after rank1's last write
    assert sch.cycles("update") == sum(sch.schedules[s].cycles for s in ("rank1", "cmp")) + 1


def test_sequence_machine_special_values():
    prog = K.chain_program(6, ROWS, COLS)
    sch = schedule_sequence(prog, 1)
    mems = _chain_memories(prog, np.random.default_rng(9), special=True)
    runs = [("all", None), ("norm", None)]
    want = mems
    for (entry, _), (words, cycles) in zip(runs, simulate_sequence(sch, mems, runs),
                                           strict=True):
        want = run_sequence(prog, want, entry)
        assert cycles == sch.cycles(entry)
        for name in prog.arrays:
            assert np.array_equal(words[name], floats_to_bits(want[name])), (entry, name)


def test_bad_programs_and_inputs_are_rejected():
    prog = K.chain_program(4, [0, 1, 3], [1, 2, 0])
    with pytest.raises(LoopError, match="unknown entry"):
        run_sequence(prog, {}, "nope")
    with pytest.raises(LoopError, match="lanes must be"):
        schedule_sequence(prog, 5)
    with pytest.raises(LoopError, match="lanes must be"):
        schedule_sequence(prog, 0)
    with pytest.raises(LoopError, match="needs 6 words"):
        run_sequence(prog, {"s": np.zeros(5)}, "prep")
    bad = SequenceProgram("bad", {**prog.arrays, "y": 3}, prog.segments, prog.entries)
    with pytest.raises(LoopError, match="array y of 4 words"):
        schedule_sequence(bad)
    bad = SequenceProgram("bad", prog.arrays, prog.segments, {"e": ("prep", "nope")})
    with pytest.raises(LoopError, match="unknown segment nope"):
        schedule_sequence(bad)
    bad = SequenceProgram("bad", prog.arrays, prog.segments, {"e": ()})
    with pytest.raises(LoopError, match="runs no segment"):
        schedule_sequence(bad)
    with pytest.raises(LoopError, match="SequenceMachine"):
        LoopMachine(modulo_schedule(K.vector_sqrt_div(3)))
    with pytest.raises(LoopError, match="load_latency 1"):
        LoopMachine(modulo_schedule(K.sym_rank1_update(3), LoopUnits(load_latency=2)))


def test_unknown_entry_number_is_ignored_and_control_grows_with_the_text():
    """``start`` with an entry number past the last does nothing (busy stays low); the
    control store has one row per segment phase, the sum of the segments' IIs."""
    from amaranth.sim import Simulator

    from navgate.opflow.sequence import SequenceMachine

    full = K.chain_program(4, [0, 1, 3], [1, 2, 0])
    prog = SequenceProgram(full.name, full.arrays, full.segments,
                           {k: full.entries[k] for k in ("all", "norm", "prep")})
    sch = schedule_sequence(prog, 1)
    dut = SequenceMachine(sch)
    assert len(dut.entry) == 2
    seen = []

    async def bench(ctx):
        ctx.set(dut.entry, 3)  # three entries: number 3 names none
        ctx.set(dut.start, 1)
        await ctx.tick()
        ctx.set(dut.start, 0)
        for _ in range(5):
            seen.append((ctx.get(dut.busy), ctx.get(dut.done)))
            await ctx.tick()
        ctx.set(dut.entry, dut.entry_index("prep"))
        ctx.set(dut.start, 1)
        await ctx.tick()
        ctx.set(dut.start, 0)
        seen.append((ctx.get(dut.busy), ctx.get(dut.done)))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert seen == [(0, 0)] * 5 + [(1, 0)]
    assert dut.control_rows == sch.control_rows == sum(s.ii for s in sch.schedules.values())


@pytest.mark.slow
def test_sequence_machine_in_verilator(tmp_path):
    """The emitted Verilog of the 1-lane machine (registered) in Verilator, driven by cocotb
    (navgate.opflow.sequence_cocotb): the same runs, words and cycles as the executor. Slow:
    the model's first build takes about 33 s of CPU (87 s wall on a busy machine; 13 s once
    Verilator's build cache holds it)."""
    from navgate.opflow.loopmachine import verilate_entries
    from navgate.opflow.sequence import SequenceMachine

    prog = K.chain_program(6, ROWS, COLS)
    sch = schedule_sequence(prog, 1)
    dut = SequenceMachine(sch)
    mems = _chain_memories(prog, np.random.default_rng(17))
    runs = [("all", None), ("norm", None), ("prep", {"s": np.array([1e-40, 0.0, -0.0, 0, 0, 0])})]
    status = verilate_entries(dut, "sequence_machine", prog.arrays, mems, runs,
                              lambda e: 2 * sch.cycles(e) + 10, tmp_path)
    want = mems
    for (entry, write), (got, cycles) in zip(runs, status, strict=True):
        want = run_sequence(prog, {**want, **(write or {})}, entry)
        assert cycles == sch.cycles(entry), entry
        words = np.concatenate([got[a] for a in prog.arrays])
        expect = np.concatenate([floats_to_bits(want[a]) for a in prog.arrays])
        assert np.array_equal(words, expect), entry
