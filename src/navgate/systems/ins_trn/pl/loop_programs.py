"""Seed 000's PL computations as loop programs: straight-line op-program segments
(:class:`navgate.opflow.ir.Program`) and loop nests (:class:`navgate.opflow.loops.LoopNest`)
that pass values through named arrays, bit for bit the fp32 engine's programs
(:func:`navgate.systems.ins_trn.pl.fp32_program.programs`).

Reference: the programs of :mod:`navgate.systems.ins_trn.pl.fp32_program` (seed 000
"Covariance Propagation", "Kalman Update Engine"); issue 29 (loop-controlled engines); the
loop-nest IR, executor and modulo scheduler of :mod:`navgate.opflow.loops`; the list
scheduler of :mod:`navgate.opflow.schedule` for the segments. docs/seed000-loop-programs.md
describes the decomposition, the exactness arguments and the cycle figures.

Programs (:func:`loop_programs`, variant ``fused``, the default)
-----------------------------------------------------------------
* ``propagate``: segment ``prop_head`` (calibration, mechanization, Phi's entries into array
  ``F``; the rows of M = G P (G = Phi - I) whose G entries are ready early or are single
  products, into array ``M``; the increments E_ij that need no other rows of M), nest
  ``cov_M`` (M's rows 3..5: chained sums over ``P`` x ``F``), nest ``cov_E`` (the increments
  that involve states 3..5: chained sums over ``M`` x ``F``), segment ``prop_tail`` (the
  velocity and position half of the mechanization, and the Kahan step of P and cP for the
  120 elements: its adds fill the slots the tail's dependency chain leaves free);
* ``alt_gate`` / ``trn_gate``: the gate programs (``trn_gate`` without its dead ops);
* ``alt_apply`` / ``trn_apply`` (gate and apply fused, run when the sequencer applies an
  update): segment ``*_gate_vec`` (the gate, C = P H', K, W = K S - C, dx, into arrays),
  nest ``*_joseph`` (the Joseph update P - C K' + K W' of the 120 elements, one element
  per iteration), segment ``*_corr`` (the state correction from dx, and the
  compensation-word reset cP <- cP - cP in its free slots).

Variant ``plain``: each part in a step of its own (head, cov_M over every row, cov_E over
every element, a Kahan nest; gate, a vector nest, a Joseph nest with the reset, the
correction). Variant ``merged``: ``fused``, but each update one straight-line segment (gate
and apply with their common ops once, :func:`fuse_programs`), the comparison that shows
what the sequential step model costs (docs/seed000-loop-programs.md).

Segments pass values to later steps through arrays (``writes``/``reads``) or as registers
(outputs that are not written to arrays; :func:`split_segment`); their commits to P and cP
go to those arrays.

Runs and cycles: :func:`run_program` (segments by :mod:`navgate.opflow.execute`, nests by
:func:`navgate.opflow.loops.run_nest` or any nest runner, e.g. the loop machine in
simulation); :func:`program_cycles` (segments by the list scheduler, nests by the modulo
scheduler); :func:`to_sequence` / :func:`sequence_cycles`: the programs as one
:class:`navgate.opflow.sequence.SequenceProgram` (every segment a one-iteration nest over a
register array ``R``), for opflow's sequence machine.

Exactness
---------
Every sum keeps the fp32 program's left-to-right order. These identities carry the rest, each
exact in float32 with round to nearest even (and in :mod:`navgate.numerics.fp32`):
``(-0) + x = x`` for every x (so a chain starts from -0 and adds its first term),
``x * 1 = x`` (a term that is a value, not a product), ``a - b = a + (-b)`` and
``(-a) * b = -(a * b)`` (a subtraction of a product rides a negated table word: the bias
rows of G hold -eps). A sum padded to a multiple of the lanes adds ``1 * (-0) = -0``, which
changes nothing. NaN results are canonical in both executors.

Chained sums (:func:`chain_sums`)
---------------------------------
A nest of many independent sums of products ``-0 + a_0 b_0 + a_1 b_1 + ...`` with ``a`` from
one array and ``b`` from another (addresses from ROM tables): each iteration adds ``u`` terms
(``u`` multiplies and a chain of ``u`` adds, one lane each), so a sum of ``n`` terms takes
``ceil(n / u)`` iterations; the sums are dealt over ``D`` tracks (interleaved iterations,
accumulator distance ``D``, longest sums first to the emptiest track), ``D`` large enough
that the chain's recurrence (``u`` adder latencies) allows II = 1. One store per iteration
(the end of a sum; one write port per array).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from navgate.gateware.fp32 import Fp32Add
from navgate.nav.eskf import N_STATES
from navgate.opflow.execute import Machine, to_f32
from navgate.opflow.ir import Builder, Program, const_name
from navgate.opflow.loops import (
    Acc,
    Addr,
    Cond,
    LoopNest,
    LoopUnits,
    LOp,
    Store,
    modulo_schedule,
    run_nest,
)
from navgate.opflow.schedule import BankedUnits, assign_banks, schedule_banked
from navgate.systems.ins_trn.pl import fp32_program as fp

__all__ = ["Segment", "LoopProgram", "chain_sums", "elementwise", "prune", "run_program",
           "loop_programs", "segment_cycles", "program_cycles", "lane_units", "P_INDEX",
           "NEG_ZERO", "ONE", "DEFAULT_LANES"]

N = N_STATES
#: stored index of P's element (i, j), i <= j (the order of fp32_program.P_REGS)
P_INDEX = {(i, j): n for n, (i, j) in enumerate((i, j) for i in range(N) for j in range(i, N))}
ONE = const_name(1.0)
NEG_ZERO = const_name(-0.0)
NEG_ZERO_VALUE = -0.0
#: the default lane count: three float32 multipliers (two DSP48E1 each) fit issue 29's
#: budget of 6 DSP48E1 for ins_engines
DEFAULT_LANES = 3


def pidx(i: int, j: int) -> int:
    return P_INDEX[min(i, j), max(i, j)]


# ------------------------------------------------------------------ loop programs


@dataclass
class Segment:
    """A straight-line program; ``reads``: register -> (array, word) loaded into it before
    the run; ``writes``: output -> (array, word) stored after it. Its commits go to the
    state registers; ``P``/``cP`` registers are read from the arrays ``P``/``cP``."""

    prog: Program
    reads: dict = field(default_factory=dict)
    writes: dict = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.prog.name


@dataclass
class LoopProgram:
    """A sequence of segments and nests over named arrays (``arrays``: name -> words;
    ``rom``: array -> {word: constant value} written before every run)."""

    name: str
    steps: list
    arrays: dict
    rom: dict = field(default_factory=dict)
    #: outputs the caller reads: name -> (array, word)
    outputs: dict = field(default_factory=dict)


#: arrays bound to state registers: array -> register names (word order)
STATE_ARRAYS = {"P": fp.P_REGS, "cP": fp.CP_REGS}
STATE_WORDS = {n: (a, i) for a, names in STATE_ARRAYS.items() for i, n in enumerate(names)}


def run_program(lp: LoopProgram, state: dict, inputs: dict | None = None, nest_runner=None):
    """Run ``lp`` from ``state`` (register name -> float32 value as float; every register of
    fp32_program.STATE_REGS) and ``inputs``; returns (new state, outputs: segment outputs
    that are not written to arrays, and ``lp.outputs``). ``nest_runner(nest, memories)``
    runs the nests (default :func:`navgate.opflow.loops.run_nest`; e.g. the loop machine in
    simulation)."""
    nest_runner = nest_runner or run_nest
    inputs = dict(inputs or {})
    regs = {k: to_f32(v) for k, v in state.items()}
    mem = {a: np.zeros(w) for a, w in lp.arrays.items()}
    for a, names in STATE_ARRAYS.items():
        if a in mem:
            mem[a][:len(names)] = [regs[n] for n in names]
    for a, words in lp.rom.items():
        for i, v in words.items():
            mem[a][i] = v
    outs: dict = {}
    passed: dict = {}  # segment outputs not written to arrays: read by later segments
    machines = _machines(lp)
    for k, step in enumerate(lp.steps):
        if isinstance(step, LoopNest):
            got = nest_runner(step, {a: mem[a].copy() for a in step.arrays})
            mem.update({a: np.asarray(v, np.float64) for a, v in got.items()})
            continue
        m = machines[k]
        p = step.prog
        for name in p.registers:
            if name in regs:
                m.set(name, regs[name])
        for a, names in STATE_ARRAYS.items():
            if a in mem:
                for i, n in enumerate(names):
                    m.regs[m.index[n]] = mem[a][i]
        for name in p.inputs:
            if name in inputs:
                m.set(name, inputs[name])
            elif name in passed:
                m.regs[m.index[name]] = passed[name]
        for name, (a, i) in step.reads.items():
            m.regs[m.index[name]] = mem[a][i]
        out = m.run(p.name)
        for reg in p.commit:
            if reg in STATE_WORDS:
                a, i = STATE_WORDS[reg]
                mem[a][i] = m.get(reg)
            else:
                regs[reg] = m.get(reg)
        for name, v in out.items():
            if name in step.writes:
                a, i = step.writes[name]
                mem[a][i] = v
            else:
                outs[name] = v
                passed[name] = v
    for a, names in STATE_ARRAYS.items():
        if a in mem:
            for i, n in enumerate(names):
                regs[n] = float(mem[a][i])
    for name, (a, i) in lp.outputs.items():
        outs[name] = float(mem[a][i])
    return regs, outs


_MACHINES: dict = {}


def _machines(lp: LoopProgram) -> dict:
    key = id(lp)
    if key not in _MACHINES:
        _MACHINES[key] = (lp, {k: Machine({s.prog.name: s.prog})
                               for k, s in enumerate(lp.steps) if isinstance(s, Segment)})
    return _MACHINES[key][1]


def prune(prog: Program, keep_outputs=None) -> Program:
    """``prog`` without the ops whose results reach no commit and no output (outputs
    restricted to ``keep_outputs`` when given)."""
    outputs = dict(prog.outputs) if keep_outputs is None else \
        {k: prog.outputs[k] for k in keep_outputs}
    live = set(prog.commit.values()) | set(outputs.values())
    ops = []
    for op in reversed(prog.ops):
        if op.dst in live:
            ops.append(op)
            live.update(op.srcs)
    ops.reverse()
    return Program(prog.name, ops=ops, inputs=prog.inputs, commit=dict(prog.commit),
                   outputs=outputs, registers=prog.registers)


# ------------------------------------------------------------------ nest builders


def chain_sums(name: str, sums: list, a_array: str, b_array: str, out_array: str,
               arrays: dict, pad: tuple, u: int = 1, tracks: int | None = None) -> LoopNest:
    """Independent sums ``-0 + A[a_0] B[b_0] + A[a_1] B[b_1] + ...`` stored to
    ``out_array[dest]`` (module docstring). ``sums``: list of (dest, [(a, b), ...]);
    ``pad``: (a, b) words whose product is -0 (1.0 and -0.0); ``u`` terms per iteration;
    ``tracks`` interleaved sums (default: enough for II = 1, ``u`` adder latencies)."""
    d = tracks or u * (Fp32Add.LATENCY + 1)  # + 1: the machine's operand register stage
    if any(not terms for _, terms in sums):
        raise ValueError(f"{name}: a sum with no terms")
    steps = [max(1, math.ceil(len(t) / u)) for _, t in sums]
    load = [0] * d
    lanes: list = [[] for _ in range(d)]
    for k in sorted(range(len(sums)), key=lambda k: (-steps[k], k)):
        tr = min(range(d), key=lambda x: (load[x], x))
        lanes[tr].append(k)
        load[tr] += steps[k]
    length = max(load)
    n_it = length * d
    a_tab = np.full((u, n_it), pad[0], np.int64)
    b_tab = np.full((u, n_it), pad[1], np.int64)
    reset = np.zeros(n_it, np.int64)
    last = np.zeros(n_it, np.int64)
    dest = np.zeros(n_it, np.int64)
    for tr in range(d):
        s = 0
        for k in lanes[tr]:
            dst, terms = sums[k]
            reset[s * d + tr] = 1
            for t, (a, b) in enumerate(terms):
                it = (s + t // u) * d + tr
                a_tab[t % u, it] = a
                b_tab[t % u, it] = b
            s += steps[k]
            last[(s - 1) * d + tr] = 1
            dest[(s - 1) * d + tr] = dst
        if s < length:  # the track's tail: pad terms, reset, never stored
            reset[s * d + tr] = 1
    ops = []
    prev = "acc"
    for q in range(u):
        ops += [LOp(f"a{q}", "load", (a_array,), Addr(f"ta{q}", (1,))),
                LOp(f"b{q}", "load", (b_array,), Addr(f"tb{q}", (1,))),
                LOp(f"p{q}", "mul", (f"a{q}", f"b{q}")),
                LOp(f"s{q}", "add", (prev, f"p{q}"))]
        prev = f"s{q}"
    tables = {f"ta{q}": a_tab[q] for q in range(u)} | {f"tb{q}": b_tab[q] for q in range(u)}
    tables |= {"reset": reset, "last": last, "dest": dest}
    return LoopNest(name, (n_it,), {a: arrays[a] for a in dict.fromkeys(
        (a_array, b_array, out_array))}, tables, ops,
        [Acc("acc", NEG_ZERO, prev, Cond("table", "reset"), d)],
        [Store(out_array, Addr("dest", (1,)), prev, Cond("table", "last"))])


def elementwise(name: str, count: int, loads: dict, ops: list, stores: list,
                arrays: dict) -> LoopNest:
    """One iteration per element, the same ops in each: ``loads``: temp -> (array,
    addresses); ``ops``: (dst, kind, a, b); ``stores``: (array, addresses, src)."""
    tables = {}
    body = []
    used = []
    for t, (a, addr) in loads.items():
        tables["t_" + t] = np.asarray(addr, np.int64)
        body.append(LOp(t, "load", (a,), Addr("t_" + t, (1,))))
        used.append(a)
    body += [LOp(d, k, (a, b)) for d, k, a, b in ops]
    st = []
    for k, (a, addr, src) in enumerate(stores):
        tables[f"st{k}"] = np.asarray(addr, np.int64)
        st.append(Store(a, Addr(f"st{k}", (1,)), src))
        used.append(a)
    for tab in tables.values():
        if len(tab) != count:
            raise ValueError(f"{name}: a table has {len(tab)} entries, not {count}")
    return LoopNest(name, (count,), {a: arrays[a] for a in dict.fromkeys(used)}, tables,
                    body, [], st)


# ------------------------------------------------------------------ propagate


#: words of the arrays: P and cP (120 state words, then ROM words), Phi's entries F
#: (15 x 15, then ROM/scalar words), M = G P (15 x 15, then ROM words), E (120)
P_WORDS = 128
P_ONE = 127
F_WORDS = 232
F_ONE, F_NEGZERO, F_QVEL, F_QATT = 225, 226, 227, 228
M_WORDS = 228
M_ONE, M_NEGZERO = 225, 226




def _propagate() -> LoopProgram:
    ins = ("wg0", "wg1", "wg2", "wa0", "wa1", "wa2")
    b = Builder("prop_head", ins, registers=fp.STATE_REGS)
    g, a = fp.emit_calibration(b, ins[:3], ins[3:])
    ft, c_old, f_n, wxyz, ixyz = fp.emit_mechanization(b, g, a, True)
    phi, _ = fp.emit_phi(b, ft, c_old, f_n, wxyz, ixyz)
    g_rows = {i: sorted(k for (r, k) in phi if r == i) for i in range(N)}
    writes = {}
    outputs = {}
    for (i, k), v in phi.items():
        if i >= 9:  # G_ii = -eps on the bias rows: M_ij = (-eps) P_ij = -(eps P_ij)
            v = b.neg(v)
        outputs[f"F{i * N + k}"] = v
        writes[f"F{i * N + k}"] = ("F", i * N + k)
    for nm, word in (("q_vel", F_QVEL), ("q_att", F_QATT)):
        outputs["F" + nm] = nm
        writes["F" + nm] = ("F", word)
    b.module = "covariance_propagator"
    for i in range(9, N):  # the bias diagonal's increment q - e2 P_ii (as the program)
        qq, e2 = ("q_ba", "e2_a") if i < 12 else ("q_bg", "e2_g")
        e = b.sub(qq, b.mul(e2, fp.p_reg(i, i)))
        outputs[f"E{i}"] = e
        writes[f"E{i}"] = ("E", pidx(i, i))
    b.prog.outputs = outputs
    head = Segment(b.prog, {}, writes)
    arrays = {"P": P_WORDS, "cP": P_WORDS, "F": F_WORDS, "M": M_WORDS, "E": len(P_INDEX)}
    rom = {"P": {P_ONE: 1.0}, "F": {F_ONE: 1.0, F_NEGZERO: NEG_ZERO_VALUE},
           "M": {M_ONE: 1.0, M_NEGZERO: NEG_ZERO_VALUE}}
    m_sums = []
    for i in range(N):
        for j in range(N):
            if i >= 9 and i == j:
                continue
            m_sums.append((i * N + j, [(pidx(k, j), i * N + k) for k in g_rows[i]]))
    e_sums = _e_sums(g_rows)
    n = len(P_INDEX)
    kahan = elementwise(
        "cov_kahan", n,
        {"e": ("E", range(n)), "c": ("cP", range(n)), "p": ("P", range(n))},
        [("y", "sub", "e", "c"), ("t", "add", "p", "y"), ("t1", "sub", "t", "p"),
         ("c2", "sub", "t1", "y")],
        [("P", range(n), "t"), ("cP", range(n), "c2")], arrays)

    return _covariance_builder(head, m_sums, e_sums, kahan, arrays, rom)


#: rows of M = G P formed in the head segment (their G entries are ready early or they are
#: single products) in the fused variant; the nest forms the others
HEAD_M_ROWS = (0, 1, 2, 6, 7, 8, 9, 10, 11, 12, 13, 14)
#: increments E_ij formed by the nest cov_E: those with i or j in these rows (their M rows
#: come from cov_M); the others in the head (i, j both in HEAD_E_ROWS: single-product rows
#: of M, ready early) or in the tail
NEST_E_ROWS = (3, 4, 5)
HEAD_E_ROWS = (0, 1, 2, 6, 7, 8, 9, 10, 11, 12, 13, 14)


def split_segment(prog: Program, head_outputs: dict, head_name: str, tail_name: str):
    """Split ``prog`` into a head (the ops its ``head_outputs`` need, and the commits of
    their results) and a tail (every other op and commit): the temporaries of the head that
    the tail reads become head outputs and tail inputs (passed as registers). Raises if the
    head would commit a register the tail still reads."""
    need = set(head_outputs.values())
    for op in reversed(prog.ops):
        if op.dst in need:
            need.update(op.srcs)
    head_ops = [op for op in prog.ops if op.dst in need]
    tail_ops = [op for op in prog.ops if op.dst not in need]
    hd = {op.dst for op in head_ops}
    imports = list(dict.fromkeys(x for op in tail_ops for x in op.srcs if x in hd))
    read_by_tail = {x for op in tail_ops for x in op.srcs}
    # a register the tail still reads keeps its value until the tail commits it (from the
    # head's result, passed on)
    late = {r for r, t in prog.commit.items() if t in hd and r in read_by_tail}
    imports += [t for r, t in prog.commit.items() if r in late and t not in imports]
    head_commit = {r: t for r, t in prog.commit.items() if t in hd and r not in late}
    head = Program(head_name, ops=head_ops, inputs=tuple(
        n for n in prog.inputs if any(n in op.srcs for op in head_ops)),
        commit=head_commit, outputs=dict(head_outputs) | {t: t for t in imports},
        registers=prog.registers)
    tail = Program(tail_name, ops=tail_ops, inputs=tuple(
        n for n in prog.inputs if any(n in op.srcs for op in tail_ops)) + tuple(imports),
        commit={r: t for r, t in prog.commit.items() if r not in head_commit},
        outputs={}, registers=prog.registers)
    return head, tail


def _propagate_fused() -> LoopProgram:
    """Calibration, mechanization, Phi, the rows HEAD_M_ROWS of M and the bias-diagonal
    increments in the head segment; nest cov_M (rows 3..5), nest cov_E; the mechanization's
    tail (velocity and position) and the Kahan step of the 120 elements in the tail segment,
    where they fill the issue slots the tail's dependency chain leaves free."""
    ins = ("wg0", "wg1", "wg2", "wa0", "wa1", "wa2")
    n = len(P_INDEX)
    b = Builder("propagate", ins + tuple(f"E{k}" for k in range(n)), registers=fp.STATE_REGS)
    g, a = fp.emit_calibration(b, ins[:3], ins[3:])
    ft, c_old, f_n, wxyz, ixyz = fp.emit_mechanization(b, g, a, True)
    phi, _ = fp.emit_phi(b, ft, c_old, f_n, wxyz, ixyz)
    g_rows = {i: sorted(k for (r, k) in phi if r == i) for i in range(N)}
    outputs, writes = {}, {}

    def out(name, value, array, word):
        outputs[name] = value
        writes[name] = (array, word)

    for (i, k), v in phi.items():
        if i < 9:
            out(f"F{i * N + k}", v, "F", i * N + k)
        else:  # G_jj = -eps for cov_E's bias columns: -(mm eps) = mm (-eps)
            out(f"F{i * N + k}", b.neg(v), "F", i * N + k)
    out("Fq_vel", "q_vel", "F", F_QVEL)
    out("Fq_att", "q_att", "F", F_QATT)
    b.module = "covariance_propagator"
    mm = {}
    for i in HEAD_M_ROWS:  # M rows as the program forms them (emit_covariance_increment)
        for j in range(N):
            if i >= 9 and i == j:
                continue
            terms = [(1, b.neg(b.mul(phi[i, i], fp.p_reg(i, j))) if i >= 9
                      else b.mul(phi[i, k], fp.p_reg(k, j))) for k in g_rows[i]]
            mm[i, j] = b.sum(terms)
            out(f"M{i * N + j}", mm[i, j], "M", i * N + j)
    e_val = {k: f"E{k}" for k in range(n)}  # the nest's results, read from array E
    q = {i: "q_vel" for i in (3, 4, 5)} | {i: "q_att" for i in (6, 7, 8)}
    for (i, j), k in P_INDEX.items():
        if i in NEST_E_ROWS or j in NEST_E_ROWS:
            continue
        if i == j and i >= 9:
            qq, e2 = ("q_ba", "e2_a") if i < 12 else ("q_bg", "e2_g")
            e_val[k] = b.sub(qq, b.mul(e2, fp.p_reg(i, i)))
            continue
        terms = [(1, mm[i, j]), (1, mm[j, i])]
        if j >= 9:
            terms.append((-1, b.mul(mm[i, j], phi[j, j])))
        else:
            terms += [(1, b.mul(mm[i, c], phi[j, c])) for c in g_rows[j]]
        if i == j and i in q:
            terms.append((1, q[i]))
        e_val[k] = b.sum(terms)
        if set((i, j)) <= set(HEAD_E_ROWS):  # ready early: formed in the head
            outputs[f"e{k}"] = e_val[k]
    for k, (i, j) in enumerate(P_INDEX):  # the Kahan step (fp32_program._kahan)
        pij, cij = fp._kahan(b, fp.p_reg(i, j), "c" + fp.p_reg(i, j), e_val[k])
        b.prog.commit[fp.p_reg(i, j)] = pij
        b.prog.commit["c" + fp.p_reg(i, j)] = cij
    head_p, tail_p = split_segment(b.prog, outputs, "prop_head", "prop_tail")
    head = Segment(head_p, {}, writes)
    tail = Segment(tail_p, {f"E{k}": ("E", k) for k in range(n) if e_val[k] == f"E{k}"}, {})
    arrays = {"P": P_WORDS, "cP": P_WORDS, "F": F_WORDS, "M": M_WORDS, "E": n}
    rom = {"P": {P_ONE: 1.0}, "F": {F_ONE: 1.0, F_NEGZERO: NEG_ZERO_VALUE},
           "M": {M_ONE: 1.0, M_NEGZERO: NEG_ZERO_VALUE}}
    m_sums = [(i * N + j, [(pidx(k, j), i * N + k) for k in g_rows[i]])
              for i in range(N) if i not in HEAD_M_ROWS for j in range(N)]
    e_sums = [(k, t) for k, t in _e_sums(g_rows)
               if e_val[k] == f"E{k}"]

    return _covariance_builder(head, m_sums, e_sums, tail, arrays, rom)


def _covariance_builder(head, m_sums, e_sums, last, arrays: dict, rom: dict):
    """The propagate program as a function of the chained sums' terms per iteration ``u``
    and ``tracks``: ``head``, the nests cov_M (M = G P over ``m_sums``) and cov_E (the
    increments over ``e_sums``), then ``last`` (the Kahan nest, or the fused tail)."""
    def build(u, tracks=None):
        return LoopProgram("propagate", [
            head,
            chain_sums("cov_M", m_sums, "P", "F", "M", arrays, (P_ONE, F_NEGZERO), u,
                       tracks),
            chain_sums("cov_E", e_sums, "M", "F", "E", arrays, (M_ONE, F_NEGZERO), u,
                       tracks),
            last], arrays, rom)

    return build


def _e_sums(g_rows) -> list:
    """The increments E_ij of the stored elements but the bias diagonal, as chained sums
    over M (A) and F (B): emit_covariance_increment's terms in its order."""
    e_sums = []
    for i in range(N):
        for j in range(i, N):
            if i == j and i >= 9:
                continue
            terms = [(i * N + j, F_ONE), (j * N + i, F_ONE)]
            if j >= 9:
                terms.append((i * N + j, j * N + j))
            else:
                terms += [(i * N + k, j * N + k) for k in g_rows[j]]
            if i == j and 3 <= i < 9:
                terms.append((M_ONE, F_QVEL if i < 6 else F_QATT))
            e_sums.append((pidx(i, j), terms))
    return e_sums


# ------------------------------------------------------------------ updates


def _scalar_arrays(names) -> dict:
    return {"s_" + n: 1 for n in names}


def _extend(prog: Program, name: str) -> Builder:
    """A builder that continues ``prog`` (its ops, outputs and commits)."""
    b = Builder(name, prog.inputs, registers=prog.registers)
    b.prog.ops = list(prog.ops)
    b._n = max(int(op.dst[1:]) for op in prog.ops)
    b.prog.commit = dict(prog.commit)
    b.prog.outputs = dict(prog.outputs)
    return b


def _with_reset(gate: Program, name: str) -> Program:
    """The gate program plus the compensation-word reset of the apply half (cP <- cP - cP,
    fp32_program._joseph), whose 120 subtractions fill the gate's free add slots."""
    b = _extend(gate, name)
    b.module = fp.RESET_MODULE
    for reg in fp.CP_REGS:
        b.prog.commit[reg] = b.sub(reg, reg)
    return b.prog


def _alt(fused: bool = False) -> tuple:
    gate = fp.altitude_gate_program()
    ops = {op.dst: op for op in gate.ops}
    # the gate's y, s and 1/s (the apply half's, bit for bit: the same ops on the same state)
    div = next(op for op in gate.ops if op.kind == "div")
    s = div.srcs[1]
    y = next(op for op in gate.ops if op.kind == "mul" and op.srcs[0] == op.srcs[1]).srcs[0]
    assert ops[s].kind == "add" and ops[y].kind == "add"
    gate.outputs = dict(gate.outputs) | {"inv": div.dst, "s": s, "y": y}
    gate.name = "alt_gate"
    scal = ("inv", "s", "y")
    arrays = {"P": P_WORDS, "cP": P_WORDS, "K": N, "C": N, "W": N, "DX": N} \
        | _scalar_arrays(scal)
    gate_seg = Segment(gate, {}, {k: ("s_" + k, 0) for k in scal})
    idx = range(N)
    if fused:  # the vector work (C, K, W = K S - C, dx) and the reset in the gate's free slots
        b = _extend(gate, "alt_gate_vec")
        b.module = "kalman_update_engine"
        writes = {}
        for i in idx:
            col = fp.p_reg(i, 2)
            k = b.mul(col, div.dst)
            for arr, v in (("K", k), ("W", b.sub(b.mul(s, k), col)), ("DX", b.mul(k, y)),
                           ("C", col)):
                b.prog.outputs[f"{arr}{i}"] = v
                writes[f"{arr}{i}"] = (arr, i)
        first = Segment(b.prog, {}, writes)
    vec = elementwise(
        "alt_vec", N,
        {"col": ("P", [pidx(i, 2) for i in idx]), "inv": ("s_inv", [0] * N),
         "s": ("s_s", [0] * N), "y": ("s_y", [0] * N)},
        [("k", "mul", "col", "inv"), ("sk", "mul", "s", "k"), ("w", "sub", "sk", "col"),
         ("dx", "mul", "k", "y")],
        [("K", idx, "k"), ("W", idx, "w"), ("DX", idx, "dx"), ("C", idx, "col")], arrays)
    ij = list(P_INDEX)
    n = len(ij)
    joseph = elementwise(
        "alt_joseph", n,
        {"p": ("P", range(n)), "cp": ("cP", range(n)), "ci": ("C", [i for i, _ in ij]),
         "kj": ("K", [j for _, j in ij]), "ki": ("K", [i for i, _ in ij]),
         "wj": ("W", [j for _, j in ij])},
        [("m1", "mul", "ci", "kj"), ("a1", "sub", "p", "m1"), ("m2", "mul", "ki", "wj"),
         ("a2", "add", "a1", "m2")]
        + ([] if fused else [("z", "sub", "cp", "cp")]),
        [("P", range(n), "a2")] + ([] if fused else [("cP", range(n), "z")]), arrays)
    if fused:
        joseph.arrays.pop("cP")
        joseph.ops = [op for op in joseph.ops if op.dst != "cp"]
        joseph.tables.pop("t_cp")
    corr = _correction("alt_corr", fused)
    gate_lp = LoopProgram("alt_gate", [gate_seg], arrays)
    apply_lp = LoopProgram("alt_apply", [first, joseph, corr] if fused else
                           [gate_seg, vec, joseph, corr], arrays,
                           outputs={f"dx{i}": ("DX", i) for i in idx})
    return gate_lp, apply_lp


def _correction(name: str, reset: bool = False) -> Segment:
    """The state correction from dx (array DX); with ``reset`` also the compensation-word
    reset, whose 120 subtractions and cP writes fill the correction chain's free slots."""
    dx = tuple(f"dx{i}" for i in range(N))
    b = Builder(name, dx, registers=fp.STATE_REGS)
    fp.emit_correction(b, list(dx))
    b.prog.outputs = {}
    prog = _with_reset(b.prog, name) if reset else b.prog
    return Segment(prog, {f"dx{i}": ("DX", i) for i in range(N)}, {})


def _trn(fused: bool = False) -> tuple:
    gate = fp.trn_gate_program()
    b = Builder("trn_gate", fp.TRN_INPUTS, registers=fp.STATE_REGS)
    cols, s, det, (i00, i01, i11), nis = fp._trn_common(b)
    # the same ops as trn_gate_program (same builder calls, same operand names)
    prog = b.prog
    prog.outputs = {"nis": nis, "accept": b.le(nis, "gate"), "positive": b.lt(0.0, det)}
    assert [(o.kind, o.srcs) for o in prog.ops] == [(o.kind, o.srcs) for o in gate.ops]
    scal = {"i00": i00, "i01": i01, "i11": i11, "s00": s[0, 0], "s01": s[0, 1],
            "s11": s[1, 1]}
    prog.outputs |= scal
    gate_seg = Segment(prune(prog), {}, {k: ("s_" + k, 0) for k in scal})
    if fused:  # C, K, W = K S - C, dx (as trn_apply_program) and the reset in the free slots
        b2 = _extend(prog, "trn_gate_vec")
        b2.module = "kalman_update_engine"
        k = [[b2.add(b2.mul(cols[0][i], i00), b2.mul(cols[1][i], i01)) for i in range(N)],
             [b2.add(b2.mul(cols[0][i], i01), b2.mul(cols[1][i], i11)) for i in range(N)]]
        writes = {}

        def put(arr, i, v):
            b2.prog.outputs[f"{arr}{i}"] = v
            writes[f"{arr}{i}"] = (arr, i)

        for i in range(N):
            for r in range(2):
                put(f"C{r}", i, cols[r][i])
                put(f"K{r}", i, k[r][i])
                put(f"W{r}", i, b2.sub(b2.sum([(1, b2.mul(s[min(r, c), max(r, c)], k[c][i]))
                                               for c in range(2)]), cols[r][i]))
            put("DX", i, b2.add(b2.mul(k[0][i], "y0"), b2.mul(k[1][i], "y1")))
        for nm in scal:
            b2.prog.outputs.pop(nm)
        b2.prog.name = "trn_gate_vec"
        first = Segment(prune(b2.prog), {}, writes)
    inputs = ("lag", "y0", "y1")
    arrays = {"P": P_WORDS, "cP": P_WORDS} | {a: N for a in (
        "C0", "C1", "K0", "K1", "W0", "W1", "DX")} | _scalar_arrays(tuple(scal) + inputs)
    in_seg = _input_segment("trn_inputs", inputs)
    idx = range(N)
    z = [0] * N
    loads = {"p0": ("P", [pidx(i, 0) for i in idx]), "p3": ("P", [pidx(i, 3) for i in idx]),
             "p1": ("P", [pidx(i, 1) for i in idx]), "p4": ("P", [pidx(i, 4) for i in idx])}
    loads |= {k: ("s_" + k, z) for k in tuple(scal) + inputs}
    vec = elementwise(
        "trn_vec", N, loads,
        [("l3", "mul", "lag", "p3"), ("c0", "sub", "p0", "l3"),
         ("l4", "mul", "lag", "p4"), ("c1", "sub", "p1", "l4"),
         ("u0", "mul", "c0", "i00"), ("u1", "mul", "c1", "i01"), ("k0", "add", "u0", "u1"),
         ("v0", "mul", "c0", "i01"), ("v1", "mul", "c1", "i11"), ("k1", "add", "v0", "v1"),
         ("w0", "mul", "s00", "k0"), ("w1", "mul", "s01", "k1"), ("sk0", "add", "w0", "w1"),
         ("x0", "mul", "s01", "k0"), ("x1", "mul", "s11", "k1"), ("sk1", "add", "x0", "x1"),
         ("wk0", "sub", "sk0", "c0"), ("wk1", "sub", "sk1", "c1"),
         ("d0", "mul", "k0", "y0"), ("d1", "mul", "k1", "y1"), ("dx", "add", "d0", "d1")],
        [("C0", idx, "c0"), ("C1", idx, "c1"), ("K0", idx, "k0"), ("K1", idx, "k1"),
         ("W0", idx, "wk0"), ("W1", idx, "wk1"), ("DX", idx, "dx")], arrays)
    ij = list(P_INDEX)
    n = len(ij)
    ii = [i for i, _ in ij]
    jj = [j for _, j in ij]
    joseph = elementwise(
        "trn_joseph", n,
        {"p": ("P", range(n)), "cp": ("cP", range(n)),
         "c0i": ("C0", ii), "k0j": ("K0", jj), "c1i": ("C1", ii), "k1j": ("K1", jj),
         "k0i": ("K0", ii), "w0j": ("W0", jj), "k1i": ("K1", ii), "w1j": ("W1", jj)},
        [("m1", "mul", "c0i", "k0j"), ("a1", "sub", "p", "m1"),
         ("m2", "mul", "c1i", "k1j"), ("a2", "sub", "a1", "m2"),
         ("m3", "mul", "k0i", "w0j"), ("a3", "add", "a2", "m3"),
         ("m4", "mul", "k1i", "w1j"), ("a4", "add", "a3", "m4")]
        + ([] if fused else [("z", "sub", "cp", "cp")]),
        [("P", range(n), "a4")] + ([] if fused else [("cP", range(n), "z")]), arrays)
    if fused:
        joseph.arrays.pop("cP")
        joseph.ops = [op for op in joseph.ops if op.dst != "cp"]
        joseph.tables.pop("t_cp")
    corr = _correction("trn_corr", fused)
    gate_lp = LoopProgram("trn_gate", [gate_seg], arrays)
    apply_lp = LoopProgram("trn_apply", [first, joseph, corr] if fused else
                           [in_seg, gate_seg, vec, joseph, corr], arrays,
                           outputs={f"dx{i}": ("DX", i) for i in idx})
    return gate_lp, apply_lp


def _input_segment(name: str, inputs) -> Segment:
    """The per-call inputs into their scalar words (the host writes them; no ops)."""
    prog = Program(name, inputs=tuple(inputs), registers=fp.STATE_REGS,
                   outputs={k: k for k in inputs})
    return Segment(prog, {}, {k: ("s_" + k, 0) for k in inputs})


#: the variants: ``plain`` (each part of the programs in a step of its own), ``fused`` (work
#: moved into the free issue slots of the segments: module docstring) and ``merged`` (fused,
#: with each update one straight-line segment: gate and apply with their common ops once)
VARIANTS = ("plain", "fused", "merged")


def fuse_programs(first: Program, second: Program, name: str) -> Program:
    """``first`` then ``second`` as one program when both read the same state and inputs and
    nothing is written between them: ``second``'s ops that repeat an op of ``first`` (same
    kind and operands after renaming) read ``first``'s result; outputs of both, commits of
    ``second`` (``first`` must commit nothing)."""
    if first.commit:
        raise ValueError(f"{first.name} commits registers: it cannot be fused before "
                         f"{second.name}")
    sig = {(op.kind, op.srcs): op.dst for op in first.ops}
    taken = {op.dst for op in first.ops}
    ren: dict = {}
    ops = list(first.ops)
    for op in second.ops:
        srcs = tuple(ren.get(x, x) for x in op.srcs)
        hit = sig.get((op.kind, srcs))
        if hit is not None:
            ren[op.dst] = hit
            continue
        dst = op.dst if op.dst not in taken else f"{op.dst}b"
        ren[op.dst] = dst
        taken.add(dst)
        sig[(op.kind, srcs)] = dst
        ops.append(type(op)(dst, op.kind, srcs, op.module))
    return Program(name, ops=ops, inputs=tuple(dict.fromkeys(first.inputs + second.inputs)),
                   commit={r: ren.get(t, t) for r, t in second.commit.items()},
                   outputs=dict(first.outputs) | {k: ren.get(v, v)
                                                   for k, v in second.outputs.items()},
                   registers=first.registers)


@lru_cache(maxsize=16)
def loop_programs(lanes: int = DEFAULT_LANES, variant: str = "fused",
                  tracks: int | None = None) -> dict:
    """The loop programs of the fp32 engine's five programs; ``lanes`` sets the terms per
    iteration of the chained sums (one per multiplier + adder lane), ``tracks`` the sums
    they interleave (default: enough for one iteration per cycle on a lane machine; a
    machine that does not overlap iterations wants 1, no padding)."""
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; known: {', '.join(VARIANTS)}")
    fused = variant != "plain"
    alt_gate, alt_apply = _alt(fused)
    trn_gate, trn_apply = _trn(fused)
    if variant == "merged":
        progs = fp.programs()
        alt_apply = LoopProgram("alt_apply", [Segment(fuse_programs(
            progs["alt_gate"], progs["alt_apply"], "alt_update"))],
            {"P": P_WORDS, "cP": P_WORDS})
        trn_apply = LoopProgram("trn_apply", [Segment(fuse_programs(
            progs["trn_gate"], progs["trn_apply"], "trn_update"))],
            {"P": P_WORDS, "cP": P_WORDS})
    prop = (_propagate_fused if fused else _propagate)()(lanes, tracks)
    return {"propagate": prop, "alt_gate": alt_gate, "alt_apply": alt_apply,
            "trn_gate": trn_gate, "trn_apply": trn_apply}


# ------------------------------------------------------------------ cycles


def lane_units(lanes: int) -> tuple[BankedUnits, LoopUnits]:
    """The units of a machine with ``lanes`` multiplier + adder lanes: the segments' list
    scheduler (one issue slot per lane and unit, the shared misc slot with the iterative
    divider and square root, split read ports) and the nests' modulo scheduler (every array
    readable by every lane)."""
    return (BankedUnits(mul=lanes, add=lanes, read_ports=2, misc_bank=False, iterative=True,
                        split_ports=True),
            LoopUnits(mul=lanes, add=lanes, read_ports=max(2, lanes)))


def _for_schedule(prog: Program) -> Program:
    """The segment as the list scheduler takes it: outputs that are sign flips or registers
    name what they flip or copy (the flip rides the write into the array, the copy is the
    register read by the nest)."""
    by = {op.dst: op for op in prog.ops}
    outs = {}
    for k, v in prog.outputs.items():
        while v in by and by[v].kind == "neg":
            v = by[v].srcs[0]
        if v in by:
            outs[k] = v
    temps = {op.dst for op in prog.ops}
    # a commit of a value another segment computed is a register copy (not modelled)
    commit = {r: t for r, t in prog.commit.items() if t in temps}
    return prune(Program(prog.name, ops=list(prog.ops), inputs=prog.inputs,
                         commit=commit, outputs=outs, registers=prog.registers))


def segment_cycles(prog: Program, units: BankedUnits) -> int:
    p = _for_schedule(prog)
    if not p.ops:
        return 0
    temps = {op.dst for op in p.ops}
    names = list(dict.fromkeys(s for op in p.ops for s in op.srcs if s not in temps))
    reads: dict = {}
    for op in p.ops:
        for s in op.srcs:
            reads[s] = reads.get(s, 0) + 1
    bank_of = assign_banks(names, units, reads)
    for reg in p.commit:
        bank_of.setdefault(reg, len(bank_of) % units.banks)
    return schedule_banked(p, units, bank_of).cycles


def program_cycles(lp: LoopProgram, lanes: int) -> list:
    """[(step name, kind, cycles, II or None)] of every step on ``lanes`` lanes."""
    seg_units, loop_units = lane_units(lanes)
    rows = []
    for step in lp.steps:
        if isinstance(step, LoopNest):
            s = modulo_schedule(step, loop_units)
            rows.append((step.name, "nest", s.cycles, s.ii))
        else:
            rows.append((step.name, "segment", segment_cycles(step.prog, seg_units), None))
    return rows


# ------------------------------------------------------------------ on opflow's sequence machine


#: the register-file array of the sequence form: every register a segment reads or writes
#: that is not a word of another array (state, configuration, inputs, passed values)
REG_ARRAY = "R"


def _segment_nest(seg: Segment, reg_index: dict, arrays: dict, imu_floats: bool) -> LoopNest:
    """A segment as a one-iteration nest of :mod:`navgate.opflow.sequence`: a load per
    register it reads (array ``R``, the arrays of P/cP and its ``reads``), its ops, a store
    per commit and per output. ``cvt`` of an IMU word reads the word as a float32 (exact for
    int16; ``imu_floats``): loop bodies have no conversion."""
    p = seg.prog
    temps = {op.dst for op in p.ops}
    home = {}  # register -> (array, word)
    for name in p.names() + list(p.outputs.values()):
        if name in temps or name.startswith("c:"):
            continue
        home[name] = seg.reads.get(name) or STATE_WORDS.get(name) or (REG_ARRAY,
                                                                       reg_index[name])
    body, loaded, used = [], {}, []

    def src(name):
        if name in temps or name.startswith("c:"):
            return name
        if name not in loaded:
            a, i = home[name]
            loaded[name] = f"ld_{len(loaded)}"
            body.append(LOp(loaded[name], "load", (a,), Addr(None, (), i)))
            used.append(a)
        return loaded[name]

    alias = {}
    for op in p.ops:
        if op.kind == "cvt":
            if not imu_floats:
                raise ValueError(f"{p.name}: cvt has no loop-body form")
            alias[op.dst] = src(op.srcs[0])
            continue
        body.append(LOp(op.dst, op.kind, tuple(alias.get(x) or src(x) for x in op.srcs)))
    stores = []

    def store(array, word, value):
        stores.append(Store(array, Addr(None, (), word), alias.get(value) or src(value)))
        used.append(array)

    for reg, t in p.commit.items():
        store(*(STATE_WORDS.get(reg) or (REG_ARRAY, reg_index[reg])), t)
    for name, t in p.outputs.items():
        store(*(seg.writes.get(name) or (REG_ARRAY, reg_index[name])), t)
    return LoopNest(p.name, (), {a: arrays[a] for a in dict.fromkeys(used)}, {}, body, [],
                    stores)


def to_sequence(lps: dict, imu_floats: bool = True):
    """The loop programs as one :class:`navgate.opflow.sequence.SequenceProgram`: every
    segment a one-iteration nest, every nest as it is, the programs its entries; returns
    (program, register index of array ``R``)."""
    from navgate.opflow.sequence import SequenceProgram

    names: list = []
    for lp in lps.values():
        for step in lp.steps:
            if isinstance(step, Segment):
                p = step.prog
                temps = {op.dst for op in p.ops}
                for n in p.names() + list(p.commit) + list(p.outputs) + list(
                        p.outputs.values()):
                    if (n not in temps and not n.startswith("c:") and n not in STATE_WORDS
                            and n not in step.reads and n not in step.writes):
                        names.append(n)
    reg_index = {n: i for i, n in enumerate(dict.fromkeys(names))}
    arrays = {REG_ARRAY: len(reg_index)}
    for lp in lps.values():
        arrays.update(lp.arrays)
    segments, entries = {}, {}
    for key, lp in lps.items():
        seq = []
        for step in lp.steps:
            if isinstance(step, Segment):
                if not (step.prog.ops or step.prog.commit or step.prog.outputs):
                    continue
                nest = _segment_nest(step, reg_index, arrays, imu_floats)
            else:
                nest = step
            nest.arrays = {a: arrays[a] for a in nest.arrays}
            segments[nest.name] = nest
            seq.append(nest.name)
        entries[key] = tuple(seq)
    return SequenceProgram("seed000", arrays, segments, entries), reg_index


def sequence_memories(lps: dict, reg_index: dict, state: dict, inputs: dict) -> dict:
    """The memories of the sequence form for a run from ``state`` and ``inputs``: P, cP,
    the ROM words, the register array (IMU words as float32)."""
    mem = {}
    for lp in lps.values():
        for a, w in lp.arrays.items():
            mem.setdefault(a, np.zeros(w))
        for a, words in lp.rom.items():
            for i, v in words.items():
                mem[a][i] = v
    for a, names in STATE_ARRAYS.items():
        mem[a][:len(names)] = [to_f32(state[n]) for n in names]
    regs = np.zeros(len(reg_index))
    for n, i in reg_index.items():
        if n in state:
            regs[i] = to_f32(state[n])
        elif n in inputs:
            regs[i] = to_f32(inputs[n])
    mem[REG_ARRAY] = regs
    return mem


def sequence_cycles(lanes: int = DEFAULT_LANES, variant: str = "fused",
                    registered: bool = True) -> dict:
    """Cycles on opflow's sequence machine (:func:`navgate.opflow.sequence.
    schedule_sequence` of :func:`to_sequence`, every array readable by every lane): entry ->
    {"steps": [(segment, II, cycles + 1)], "cycles": start to done}, and "control_rows"."""
    from navgate.opflow.sequence import schedule_sequence

    prog, _ = to_sequence(loop_programs(lanes, variant))
    s = schedule_sequence(prog, lanes, read_ports=max(2, lanes), registered=registered)
    out: dict = {e: {"steps": [(n, s.schedules[n].ii, s.schedules[n].cycles + 1)
                               for n in segs], "cycles": s.cycles(e)}
                 for e, segs in prog.entries.items()}
    out["control_rows"] = s.control_rows
    return out
