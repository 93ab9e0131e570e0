"""Loop nests of opflow: the Numba executor against the bit-true interpreter on the unrolled
nest and against numpy float32 arithmetic, the modulo scheduler's II bounds and exact cycles,
and the rejection of malformed nests."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.gateware.fp32 import Fp32Add, Fp32Mul
from navgate.numerics.fp32 import floats_to_bits
from navgate.opflow import loop_kernels as K
from navgate.opflow.execute import run_bittrue
from navgate.opflow.ir import const_name
from navgate.opflow.loops import (
    TRANSFER_LATENCY,
    Acc,
    Addr,
    Cond,
    LoopError,
    LoopNest,
    LoopUnits,
    LOp,
    Store,
    check_nest,
    lane_plan,
    modulo_schedule,
    run_nest,
    schedule_beside,
    unroll,
)


def kernels(rows, cols):
    return [K.sym_rank1_update(6), K.sym_rank1_update(4, 0.5), K.dense_matvec(3, 5),
            K.dense_matvec(2, 4, bias=True), K.dense_matvec_interleaved(3, 4),
            K.sparse_matvec(rows, cols, 6, 6)]


def bits(values):
    return floats_to_bits(values)


@pytest.mark.parametrize("special", [False, True])
def test_executor_equals_bittrue_interpreter_on_the_unrolled_nest(special, loop_data):
    rng = np.random.default_rng(7 + special)
    for nest in kernels(loop_data.rows, loop_data.cols):
        for _ in range(3):
            mems = loop_data.memories(nest, rng, special)
            got = run_nest(nest, mems)
            prog, regs = unroll(nest)
            state = {r: bits([mems[a][i]])[0] for r, (a, i) in regs.items()}
            new, _, _ = run_bittrue(prog, state, {})
            for r, (a, i) in regs.items():
                assert int(new[r][0]) == int(bits([got[a][i]])[0]), (nest.name, r)


def test_kernels_compute_what_they_say_in_float32(loop_data):
    """Against numpy float32 arithmetic (IEEE round to nearest even; normal operands)."""
    rng = np.random.default_rng(3)
    memories = loop_data.memories
    SPMV_ROWS, SPMV_COLS = loop_data.rows, loop_data.cols  # noqa: N806
    f = np.float32
    nest = K.sym_rank1_update(7, 0.5)
    mems = memories(nest, rng)
    got = run_nest(nest, mems)["P"]
    rows, cols = K.upper_index(7)
    k = mems["k"].astype(f)
    want = mems["P"].astype(f) + (f(0.5) * k[rows]) * k[cols]
    assert np.array_equal(bits(got), bits(want))
    nest = K.sparse_matvec(SPMV_ROWS, SPMV_COLS, 6, 6)
    mems = memories(nest, rng)
    got = run_nest(nest, mems)["y"]
    want = mems["y"].astype(f)
    for r in set(SPMV_ROWS):
        acc = f(0.0)
        for n, (rr, c) in enumerate(zip(SPMV_ROWS, SPMV_COLS, strict=True)):
            if rr == r:
                acc = f(acc + f(mems["a"][n]) * f(mems["x"][c]))
        want[r] = acc
    assert np.array_equal(bits(got), bits(want))  # rows 1 and 4 untouched
    nest = K.dense_matvec(3, 5)
    mems = memories(nest, rng)
    got = run_nest(nest, mems)["y"]
    a = mems["A"].astype(f).reshape(3, 5)
    want = np.zeros(3, f)
    for c in range(5):
        want = want + a[:, c] * mems["x"].astype(f)[c]
    assert np.array_equal(bits(got), bits(want))


def _check_schedule(s):
    nest, ii = s.nest, s.ii
    accs = nest.acc_names()
    seen = set()
    for key, got in s.resource.items():
        if got is None:  # a sign flip: no unit
            continue
        res, inst = got
        slot = (res, inst, s.time[key] % ii)
        assert slot not in seen, slot
        seen.add(slot)
    for op in nest.ops:
        t = s.time[op.dst]
        assert t >= 1
        for src in op.srcs if op.kind != "load" else ():
            if src in accs:
                assert s.ready[accs[src].update] - accs[src].distance * ii <= t  # recurrence
            elif not src.startswith("c:"):
                assert s.ready[src] <= t
    for k, st in enumerate(nest.stores):
        assert s.time[("store", k)] >= s.ready[st.src]
        assert s.time[("store", k)] < s.depth


def test_modulo_schedule_ii_bounds_and_exact_cycles(loop_data):
    lat_add, lat_mul = Fp32Add.LATENCY, Fp32Mul.LATENCY
    # rank-1 update, 21 stored elements: 1 mul + 1 add + 3 loads + 1 store per element
    s = modulo_schedule(K.sym_rank1_update(6))
    assert (s.ii, s.res_mii, s.rec_mii) == (1, 1, 1)
    # loads at 1, product at 2 (load + 1), sum at 2 + 5, store at 7 + 8 = 15: depth 16
    assert s.time == {"p": 1, "ki": 1, "kj": 1, "kk": 2, "q": 2 + lat_mul,
                      ("store", 0): 2 + lat_mul + lat_add}
    assert s.depth == 16 and s.cycles == 20 * 1 + 16
    # one read port: k is read twice per iteration, so II = 2 (resource bound)
    s1 = modulo_schedule(K.sym_rank1_update(6), LoopUnits(read_ports=1))
    assert (s1.ii, s1.res_mii) == (2, 2) and s1.cycles == 20 * 2 + s1.depth
    # two multiplies on one multiplier: II 2; on two: II 1
    assert modulo_schedule(K.sym_rank1_update(6, 0.5)).ii == 2
    assert modulo_schedule(K.sym_rank1_update(6, 0.5), LoopUnits(mul=2)).ii == 1
    # accumulations: the adder's latency is the recurrence bound
    for nest in (K.sparse_matvec(loop_data.rows, loop_data.cols, 6, 6), K.dense_matvec(3, 5)):
        s = modulo_schedule(nest)
        assert (s.ii, s.rec_mii, s.res_mii) == (lat_add, lat_add, 1)
        assert s.cycles == (nest.iterations - 1) * lat_add + 16
    # interleaved row sums: the recurrence bound is the adder latency over the distance
    for rows, ii in ((3, 3), (4, 2), (8, 1), (15, 1)):
        s = modulo_schedule(K.dense_matvec_interleaved(rows, 5))
        assert (s.ii, s.rec_mii) == (ii, -(-lat_add // rows))
        assert s.cycles == (rows * 5 - 1) * ii + 16
    for nest in kernels(loop_data.rows, loop_data.cols):
        for units in (LoopUnits(), LoopUnits(read_ports=1), LoopUnits(mul=2, add=2)):
            _check_schedule(modulo_schedule(nest, units))


def test_interleaved_sums_are_the_same_bits():
    """Row sums carried at distance n_rows keep each row's order: the same bits as the
    row-by-row nest."""
    rng = np.random.default_rng(11)
    for rows, cols in ((3, 4), (15, 15), (1, 6)):
        a, b = K.dense_matvec(rows, cols), K.dense_matvec_interleaved(rows, cols)
        for _ in range(3):
            mems = {k: rng.standard_normal(w) * 10.0 ** rng.integers(-8, 8, w)
                    for k, w in a.arrays.items()}
            assert np.array_equal(bits(run_nest(a, mems)["y"]), bits(run_nest(b, mems)["y"]))


def _nest(ops, stores, accs=(), trips=(4,), arrays=None, tables=None):
    return LoopNest("bad", trips, arrays or {"a": 4, "b": 4}, tables or {}, list(ops),
                    list(accs), list(stores))


LOAD_A = LOp("x", "load", ("a",), Addr(None, (1,)))


@pytest.mark.parametrize("nest, message", [
    (_nest([LOAD_A, LOp("y", "add", ("x", "x"))], [Store("a", Addr(None, (1,), 1), "y",
                                                         None)]),
     "out of range"),
    (_nest([LOp("x", "load", ("a",), Addr(None, (1,), 1)), LOp("y", "add", ("x", "x"))],
           [Store("a", Addr(None, (1,)), "y")], trips=(3,)),
     "carry it in an accumulator"),
    (_nest([LOAD_A, LOp("y", "add", ("x", "x"))], [Store("b", Addr(None, (0,)), "y")]),
     "written in iterations"),
    (_nest([LOAD_A, LOp("y", "cvt", ("x",))], []), "op kind"),
    (_nest([LOAD_A, LOp("y", "sqrt", ("x", "x"))], []), "takes 1 source"),
    (_nest([LOAD_A, LOp("y", "div", ("x",))], []), "takes 2 source"),
    (_nest([LOAD_A, LOp("y", "add", ("x", "z"))], []), "before it is defined"),
    (_nest([LOAD_A, LOp("x", "add", ("x", "x"))], []), "defined twice"),
    (_nest([LOAD_A], [], trips=(0,)), "trip counts"),
    (_nest([LOAD_A, LOp("y", "add", ("s", "x"))], [],
           [Acc("s", const_name(0.0), "y", Cond("table", "f"))], tables={"f": [1, 0]}),
     "flag table"),
    (_nest([LOp("x", "load", ("a",), Addr("t", (1,)))], [], tables={"t": [0, 1, 2]}),
     "out of range"),
    (_nest([LOAD_A, LOp("y", "add", ("s", "x"))], [],
           [Acc("s", const_name(0.0), "y", Cond("first", 3))]), "no loop level"),
    (_nest([LOAD_A, LOp("y", "add", ("s", "x"))], [],
           [Acc("s", const_name(0.0), "y", Cond("first", 0), 2)]), "read before its first"),
    (_nest([LOAD_A, LOp("y", "add", ("s", "x"))], [],
           [Acc("s", const_name(0.0), "y", Cond("first", 0), 0)]), "distance must be"),
])
def test_malformed_nests_are_rejected(nest, message):
    with pytest.raises(LoopError, match=message):
        check_nest(nest)
    with pytest.raises(LoopError, match=message):
        modulo_schedule(nest)


def test_in_place_update_of_the_same_word_is_allowed_and_run_in_order():
    """A word read and written by the same iteration only (the rank-1 update's P) is no
    recurrence: the store is scheduled after the load."""
    nest = K.sym_rank1_update(3)
    check_nest(nest)
    s = modulo_schedule(nest)
    assert s.time[("store", 0)] > s.time["p"]
    with pytest.raises(LoopError, match="needs 6 words"):
        run_nest(nest, {"P": np.zeros(5), "k": np.zeros(3)})


def test_result_ports_limit_the_results_landing_in_a_cycle(loop_data):
    """The what-if of a register file's write ports (``LoopUnits.result_ports``): at most
    that many unit results land in one cycle (modulo II for a nest, in absolute cycles for a
    straight line); the rank-1 update's product and sum (two results an iteration) need II 2
    on one port and keep II 1 on two."""
    assert modulo_schedule(K.sym_rank1_update(6), LoopUnits(result_ports=2)).ii == 1
    one = modulo_schedule(K.sym_rank1_update(6), LoopUnits(result_ports=1))
    assert (one.ii, one.res_mii) == (2, 2)
    for nest in kernels(loop_data.rows, loop_data.cols):
        for ports in (1, 2):
            units = LoopUnits(mul=2, add=2, result_ports=ports)
            s = modulo_schedule(nest, units)
            _check_schedule(s)
            period = s.ii if nest.iterations > 1 else None
            landing: dict = {}
            for op in nest.ops:
                if op.kind in ("load", "neg"):
                    continue
                t = s.ready[op.dst]
                key = t % period if period else t
                landing[key] = landing.get(key, 0) + 1
            assert max(landing.values()) <= ports, (nest.name, ports)
    # a straight line (seed 000's altitude correction): absolute cycles, and a longer one
    from navgate.systems.ins_trn.pl import loop_programs as LP

    prog, _ = LP.to_sequence(LP.loop_programs(3, "plain"))
    seg = prog.segments["alt_corr"]
    free = modulo_schedule(seg, LoopUnits(mul=3, add=3, read_ports=3))
    one = modulo_schedule(seg, LoopUnits(mul=3, add=3, read_ports=3, result_ports=1))
    lands = [one.ready[op.dst] for op in seg.ops if op.kind not in ("load", "neg")]
    assert len(lands) == len(set(lands)) and one.cycles > free.cycles


def _check_lanes(s):
    """The rules of lanes as clusters (``LoopUnits.transfers``): every op on an instance of
    its planned lane; every operand made in another lane sent there by a transfer that
    issues once the value is ready and lands by the read (an accumulator's update by the
    read ``distance`` iterations on); at most ``transfers`` transfers into a lane a cycle
    (modulo II)."""
    nest, ii, units = s.nest, s.ii, s.units
    plan = lane_plan(nest, units)
    alias = {op.dst: op.srcs[0] for op in nest.ops if op.kind == "neg"}

    def root(x):
        while x in alias:
            x = alias[x]
        return x

    accs = nest.acc_names()
    for op in nest.ops:
        if op.kind == "neg":
            continue
        res, inst = s.resource[op.dst]
        assert inst % units.lanes == plan[op.dst], op
        if op.kind == "load":
            continue
        for x in map(root, op.srcs):  # (through a sign flip)
            if x.startswith("c:"):
                continue
            reads = []
            if x in accs:
                a = accs[x]
                if not root(a.init).startswith("c:"):
                    reads.append((root(a.init), root(a.init), s.time[op.dst]))
                if nest.iterations > 1:
                    reads.append((root(a.update), a.name, s.time[op.dst] + a.distance * ii))
            else:
                reads.append((x, x, s.time[op.dst]))
            for v, key, t in reads:
                if plan[v] == plan[op.dst]:
                    continue
                sent = s.transfers[(key, plan[op.dst])]
                assert s.ready[v] <= sent and sent + TRANSFER_LATENCY <= t, (op, v)
    into: dict = {}
    for (_, lane), t in s.transfers.items():
        into[(lane, t % ii)] = into.get((lane, t % ii), 0) + 1
    assert max(into.values(), default=0) <= units.transfers


def test_lanes_as_clusters_send_every_operand_of_another_lane(loop_data):
    """The what-if of the fast engine's brief (``LoopUnits.transfers``): each lane reads the
    values it made; one of another lane crosses on a transfer one cycle long, at most
    ``transfers`` into a lane a cycle. Seed 000's chained sums (three products a term, the
    adds chained across the lanes) need their interleave to cover the three transfers: over
    27 sums (the adder's 9 cycles x 3) the recurrence bound becomes 2, over 30 it stays 1."""
    from navgate.systems.ins_trn.pl import loop_programs as LP

    units = LoopUnits(mul=3, add=3, read_ports=3, load_latency=2, operand_stage=1)
    clustered = LoopUnits(mul=3, add=3, read_ports=3, load_latency=2, operand_stage=1,
                          transfers=1)
    for tracks, free_ii, lanes_ii in ((None, 1, 2), (30, 1, 1)):
        prog, _ = LP.to_sequence(LP.loop_programs(3, "fused", tracks=tracks))
        nest = prog.segments["cov_M"]
        assert nest.accs[0].distance == (tracks or 27)
        assert modulo_schedule(nest, units).ii == free_ii
        s = modulo_schedule(nest, clustered)
        assert (s.ii, s.rec_mii) == (lanes_ii, lanes_ii)
        _check_schedule(s)
        _check_lanes(s)
        # the adds chain across the three lanes: s0 -> s1 -> s2 -> the next term's s0
        assert len(s.transfers) == 3
    # the straight lines of an update and the kernels, one and two transfers a lane
    prog, _ = LP.to_sequence(LP.loop_programs(3, "plain"))
    nests = [prog.segments["alt_corr"]] + kernels(loop_data.rows, loop_data.cols)
    for nest in nests:
        for transfers in (1, 2):
            s = modulo_schedule(nest, LoopUnits(mul=3, add=3, read_ports=3,
                                                transfers=transfers))
            _check_schedule(s)
            _check_lanes(s)
    s = modulo_schedule(prog.segments["alt_corr"], clustered)
    assert s.transfers and s.cycles > modulo_schedule(prog.segments["alt_corr"], units).cycles
    with pytest.raises(LoopError, match="as many multipliers"):
        modulo_schedule(K.dense_matvec(3, 5), LoopUnits(mul=1, add=2, transfers=1))


@pytest.mark.parametrize("late", ["loads", "all"])
def test_late_ops_keep_the_cycles_and_shorten_the_lives(loop_data, late):
    """``LoopUnits.late``: the loads (or every op) move as late as their values' reads, the
    stores of a load's array and their units allow; stores and transfers stay, so the cycles
    and every rule of the schedule hold; each moved op is as late as it can be (one cycle
    later breaks a read, a store's order or its unit's slot)."""
    from navgate.systems.ins_trn.pl import loop_programs as LP

    prog, _ = LP.to_sequence(LP.loop_programs(3, "fused", tracks=30))
    nests = [prog.segments[n] for n in ("prop_head", "cov_M", "prop_tail")]
    nests += kernels(loop_data.rows, loop_data.cols)
    moved = 0

    def reads_of(s):
        """value -> the offsets at which it is read (its readers, through sign flips and
        accumulators, its stores and its transfers)."""
        alias = {op.dst: op.srcs[0] for op in s.nest.ops if op.kind == "neg"}
        accs = s.nest.acc_names()

        def root(x):
            while x in alias:
                x = alias[x]
            return x

        out: dict = {}
        for op in s.nest.ops:
            if op.kind in ("load", "neg"):
                continue
            for x in op.srcs:
                if x in accs:
                    a = accs[x]
                    out.setdefault(root(a.init), []).append(s.time[op.dst])
                    if s.nest.iterations > 1:
                        out.setdefault(root(a.update), []).append(
                            s.time[op.dst] + a.distance * s.ii)
                else:
                    out.setdefault(root(x), []).append(s.time[op.dst])
        for k, st in enumerate(s.nest.stores):
            out.setdefault(root(st.src), []).append(s.time[("store", k)])
        for (v, _), t in s.transfers.items():
            out.setdefault(root(accs[v].update) if v in accs else v, []).append(t)
        return out

    for nest in nests:
        for transfers in (0, 1):
            base = dict(mul=3, add=3, read_ports=3, load_latency=2, operand_stage=1,
                        transfers=transfers)
            early = modulo_schedule(nest, LoopUnits(**base))
            s = modulo_schedule(nest, LoopUnits(**base, late=late))
            assert (s.ii, s.cycles, s.transfers) == (early.ii, early.cycles, early.transfers)
            _check_schedule(s)
            if transfers:
                _check_lanes(s)
            reads_at = reads_of(s)
            taken = {(s.resource[o.dst], (s.time[o.dst] + j) % s.ii)
                     for o in nest.ops if o.kind != "neg"
                     for j in range(s.units.occupancy(o.kind))}
            updates = {a.update for a in nest.accs}
            for op in nest.ops:
                if op.kind == "neg" or (late == "loads" and op.kind != "load") or (
                        op.dst in updates):  # an accumulator's update stays
                    if op.kind != "neg":
                        assert s.time[op.dst] == early.time[op.dst]
                    continue
                assert s.time[op.dst] >= early.time[op.dst]
                moved += s.time[op.dst] - early.time[op.dst]
                stores = [s.time[("store", k)] for k, st in enumerate(nest.stores)
                          if op.kind == "load" and st.array == op.srcs[0]
                          and not (st.addr.table is None and op.addr.table is None
                                   and not any(st.addr.strides) and not any(op.addr.strides)
                                   and st.addr.offset != op.addr.offset)]
                assert all(s.time[op.dst] < t for t in stores)
                t = s.time[op.dst] + 1
                occ = s.units.occupancy(op.kind)
                mine = {(s.resource[op.dst], (s.time[op.dst] + j) % s.ii) for j in range(occ)}
                reads = reads_at.get(op.dst, [])
                assert (not reads or any(t + s.units.latency(op.kind) > r for r in reads)
                        or any(t >= u for u in stores)
                        or any((s.resource[op.dst], (t + j) % s.ii) in taken - mine
                               for j in range(occ))), (nest.name, op)
    assert moved > 0  # the mechanization's words and products made early and read late


def test_a_nest_beside_a_straight_line_takes_only_free_slots():
    """``schedule_beside`` (a what-if of the fast engine's brief): the line's ops and
    stores take no slot the nest's iterations hold, keep their rules, and the pair ends
    when the later ends; arrays must be disjoint. The altitude update's Joseph nest keeps
    every adder busy (II 1 on three lanes), so its correction stretches."""
    from navgate.systems.ins_trn.pl import loop_programs as LP

    prog, _ = LP.to_sequence(LP.loop_programs(3, "plain"))
    units = LoopUnits(mul=3, add=3, read_ports=3, load_latency=2, operand_stage=1)
    nest, line = prog.segments["alt_joseph"], prog.segments["alt_corr"]
    looped, straight, cycles = schedule_beside(nest, line, units)
    alone = modulo_schedule(line, units)
    assert looped.ii == 1 and cycles == max(looped.cycles, straight.depth)
    assert straight.depth > alone.depth
    _check_schedule(straight)
    kinds = {op.dst: op.kind for op in nest.ops}
    held = {(got, k * looped.ii + looped.time[key] + j)
            for key, got in looped.resource.items() if got is not None
            for k in range(nest.iterations)
            for j in range(units.occupancy(kinds.get(key, "store")))}
    line_kinds = {op.dst: op.kind for op in line.ops}
    for key, got in straight.resource.items():
        if got is not None:
            occ = units.occupancy(line_kinds.get(key, "store"))
            assert all((got, straight.time[key] + j) not in held for j in range(occ)), key
    with pytest.raises(LoopError, match="share arrays"):
        schedule_beside(nest, LoopNest("x", (), {"P": 128},
                                       ops=[LOp("a", "load", ("P",), Addr())]), units)
    with pytest.raises(LoopError, match="a loop nest beside a straight line"):
        schedule_beside(line, nest, units)


def test_sign_flips_of_accumulators_and_constants_and_a_dead_recurrence():
    """The what-ifs on the corners the seed programs do not reach: a sign flip of an
    accumulator (read through it, its update's lane), a sign flip of a constant, and an
    accumulator read by nothing but itself beside a divider (its update stays: moving it
    would pull its own next read later without end)."""
    zero = const_name(0.0)
    negacc = LoopNest("negacc", (4,), {"a": 4, "o": 4}, {},
                      [LOp("x", "load", ("a",), Addr(None, (1,))), LOp("n", "neg", ("acc",)),
                       LOp("s", "add", ("n", "x"))],
                      [Acc("acc", zero, "s", Cond("first", 0))],
                      [Store("o", Addr(None, (1,)), "s")])
    negc = LoopNest("negc", (), {"a": 4}, {},
                    [LOp("x", "load", ("a",), Addr(None, (), 0)),
                     LOp("m", "neg", (const_name(2.0),)), LOp("s", "mul", ("m", "x"))],
                    [], [Store("a", Addr(None, (), 1), "s")])
    dead = LoopNest("dead", (4,), {"a": 4, "o": 4}, {},
                    [LOp("x", "load", ("a",), Addr(None, (1,))), LOp("s", "add", ("acc", "x")),
                     LOp("y", "div", ("x", "x"))],
                    [Acc("acc", zero, "s", Cond("first", 0))],
                    [Store("o", Addr(None, (1,)), "y")])
    for nest in (negacc, negc, dead):
        base = modulo_schedule(nest, LoopUnits(mul=3, add=3, read_ports=3))
        for extra in ({"transfers": 1}, {"late": "loads"}, {"late": "all"},
                      {"transfers": 1, "late": "all"}):
            s = modulo_schedule(nest, LoopUnits(mul=3, add=3, read_ports=3, **extra))
            _check_schedule(s)
            if "transfers" in extra:
                _check_lanes(s)
            else:
                assert (s.ii, s.cycles) == (base.ii, base.cycles)
            assert max(s.ready.values()) <= s.depth
    with pytest.raises(LoopError, match="late must be"):
        modulo_schedule(dead, LoopUnits(late="everything"))
