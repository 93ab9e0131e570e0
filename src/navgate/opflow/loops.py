"""Loop nests in opflow: the IR of a float32 loop nest, its bit-true executor (Numba) and a
modulo scheduler for its body.

Reference: iterative modulo scheduling (B. R. Rau, "Iterative modulo scheduling", MICRO-27,
1994; the initiation interval II bounded below by the resource bound ResMII and the
recurrence bound RecMII); address generation by strength reduction of affine indices and
ROM tables, as in the loop accelerators of high-level synthesis (Gajski et al.,
"High-Level Synthesis", 1992, ch. 8). :mod:`navgate.opflow.loopmachine` turns a schedule
into an Amaranth sequencer and datapath that runs the nest bit for bit like
:func:`run_nest`.

IR
--
A :class:`LoopNest` has ``trips`` (trip counts, outermost first; the iterations are run in
row-major order and numbered ``n = 0 .. N-1``), ``arrays`` (float32 memories: name ->
words), ``tables`` (ROMs of non-negative integers) and a body run once per iteration:

* :class:`Addr`: ``index = offset + sum(strides[l] * i_l)`` over the loop indices; the
  address is ``index``, or ``tables[table][index]`` when ``table`` is set (a sparse
  matrix's non-zeros, the upper-triangle map of a symmetric matrix);
* :class:`Cond`: a per-iteration flag: ``("first", l)`` (every index from level ``l``
  inwards is 0), ``("last", l)`` (each is its trip count - 1), ``("at_first", l)`` /
  ``("at_last", l)`` (the index of level ``l`` alone) or ``("table", name)``
  (``tables[name][n] != 0``, one entry per iteration);
* ops (:class:`LOp`, SSA temporaries ``dst``): ``load`` (``srcs = (array,)``, ``addr``),
  ``add``, ``sub``, ``mul``, ``div``, ``sqrt`` (one source), ``neg`` (one source: a sign
  flip, NaN in -> canonical NaN out, as :func:`navgate.numerics.fp32.fp32_neg`), ``lt`` and
  ``le`` (1.0 when the comparison holds, else 0.0; false when a NaN is involved) on float32
  (:mod:`navgate.numerics.fp32` rounding, subnormals flushed); a source is a temporary of
  the same iteration, a constant ``c:<hex>`` (:func:`navgate.opflow.ir.const_name`) or an
  accumulator;
* :class:`Acc`: a loop-carried value: read as ``init`` (a constant or a temporary) in an
  iteration where ``reset`` holds, otherwise as the value of ``update`` (a temporary) in
  the iteration ``distance`` before (1: the previous one; ``d`` > 1 interleaves ``d``
  independent sums, e.g. the rows of a matrix-vector product with the row loop inside:
  each row's sum keeps its order, and the recurrence bound drops to latency / d);
* :class:`Store`: ``array[addr] <- src`` at the end of an iteration where ``when`` holds
  (always when None).

Semantics (:func:`run_nest`): iterations in order; each reads the memories as left by the
iterations before it. :func:`check_nest` rejects a nest whose memories carry a value from one
iteration to another (an address written in one iteration and read or written in another):
such a value must ride an accumulator, so that the pipelined machine, which overlaps
iterations, computes the same numbers.

Scheduling (:func:`modulo_schedule`)
------------------------------------
One iteration starts every II cycles; every op has a fixed offset in its iteration. Resources
per cycle modulo II: ``mul`` and ``add`` units (add/sub; fully pipelined, latencies of
:mod:`navgate.gateware.fp32`), a ``cmp`` unit (lt/le, :class:`~navgate.gateware.fp32.Fp32Compare`,
pipelined), the iterative ``div`` and ``sqrt`` units (:class:`~navgate.gateware.fp32.Fp32DivIter`,
:class:`~navgate.gateware.fp32.Fp32SqrtIter`: not pipelined, an op blocks its unit for the
core's ``INTERVAL`` cycles, so they count ``INTERVAL`` times in ResMII and II >= INTERVAL for a
nest that uses one), ``read_ports`` read ports and one write port per array. An
iteration's addresses and flags are ready at offset 1 (one ROM read; they then ride delay
lines to their ops), a load's word one cycle after it is issued, a unit's result ``L`` cycles
after issue; an op reads its operands in its issue cycle from the delay line of the unit
that made them. A store is issued after every load of its array in the iteration (the read
sees the old word). An accumulator read at offset ``t`` whose update is ready at ``r``
needs ``r - distance II <= t`` (the recurrence). ResMII = max over resources of uses /
instances; RecMII = max over accumulators of ``(r - t) / distance`` (rounded up) in the
schedule without resource limits; II
starts at max(ResMII, RecMII) and grows until the greedy placement (topological order,
each op at its earliest free slot) fits. Cycles of a nest: ``(N - 1) * II + depth``, depth
the offset after an iteration's last result is written. ``neg`` takes no unit and no time:
its value is its source's, sign flipped on the consumer's operand path. A nest of one
iteration (a straight-line segment, ``trips == ()``) is list-scheduled without wrap-around and
gets II = depth: cycle by cycle, the ready ops by priority, the priority an op's height (the
longest latency path from its issue to the segment's end, as
:mod:`navgate.opflow.schedule`), where a store counts the stores of its array that must
follow it through the one write port (ranked by the earliest cycle their word can be ready)
and a load the stores of its array that wait for it; stores then take their array's write
port in the order their words are ready. Of that schedule and the greedy topological
placement the shorter is kept (the critical path has won on every client segment measured so
far; the clients' documents give the figures).

What-ifs of the fast engine's brief (docs/opflow-register-machine.md section 7; no machine
here runs them): :attr:`LoopUnits.result_ports` (unit results landing per cycle),
:attr:`LoopUnits.transfers` (lanes as clusters: an op reads what its lane made, a value of
another lane crosses on a transfer, the lanes planned by :func:`lane_plan`) and
:attr:`LoopUnits.late` (ops moved as late as their values' reads allow, the cycles kept) and
:func:`schedule_beside` (a straight line in the slots a loop nest leaves free).
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from navgate.gateware.fp32 import Fp32Add, Fp32Compare, Fp32DivIter, Fp32Mul, Fp32SqrtIter
from navgate.opflow.execute import round_fp32
from navgate.opflow.ir import Op, Program, const_value

__all__ = ["Addr", "Cond", "LOp", "Acc", "Store", "LoopNest", "LoopError", "check_nest",
           "iteration_indices", "addresses", "flags", "run_nest", "unroll", "LoopUnits",
           "LoopSchedule", "modulo_schedule", "lane_plan", "schedule_beside", "ADDR_READY",
           "LOAD_LATENCY", "TRANSFER_LATENCY", "LOOP_KINDS", "UNARY", "UNIT_OF"]

LOOP_KINDS = ("load", "add", "sub", "mul", "div", "sqrt", "neg", "lt", "le")
#: kinds with one float source (the others but ``load`` take two)
UNARY = ("sqrt", "neg")
#: the unit each kind runs on (``neg`` runs on none: a sign flip on an operand path)
UNIT_OF = {"load": "read", "add": "add", "sub": "add", "mul": "mul", "div": "div",
           "sqrt": "sqrt", "neg": None, "lt": "cmp", "le": "cmp"}
#: offset at which an iteration's addresses and flags are ready (one ROM/register stage)
ADDR_READY = 1
#: a load's word is ready one cycle after its address is presented (synchronous read)
LOAD_LATENCY = 1
#: a value sent to another lane (:attr:`LoopUnits.transfers`) is readable there this many
#: cycles after its transfer issues
TRANSFER_LATENCY = 1


class LoopError(ValueError):
    """A malformed loop nest or one the machine cannot run as written."""


@dataclass(frozen=True)
class Addr:
    table: str | None = None
    strides: tuple = ()
    offset: int = 0


@dataclass(frozen=True)
class Cond:
    kind: str  #: "first", "last", "at_first", "at_last" or "table"
    arg: object  #: level (first/last) or table name


@dataclass(frozen=True)
class LOp:
    dst: str
    kind: str
    srcs: tuple
    addr: Addr | None = None


@dataclass(frozen=True)
class Acc:
    name: str
    init: str
    update: str
    reset: Cond
    distance: int = 1  #: the update read back is that of ``distance`` iterations before


@dataclass(frozen=True)
class Store:
    array: str
    addr: Addr
    src: str
    when: Cond | None = None


@dataclass
class LoopNest:
    name: str
    trips: tuple
    arrays: dict  #: name -> words
    tables: dict = field(default_factory=dict)  #: name -> sequence of non-negative ints
    ops: list = field(default_factory=list)
    accs: list = field(default_factory=list)
    stores: list = field(default_factory=list)

    @property
    def iterations(self) -> int:
        return int(np.prod(self.trips)) if self.trips else 1

    def acc_names(self) -> dict:
        return {a.name: a for a in self.accs}


# ------------------------------------------------------------------ iteration space


def iteration_indices(nest: LoopNest) -> np.ndarray:
    """(N, levels) loop indices of every iteration, in order (row-major)."""
    if not nest.trips:
        return np.zeros((1, 0), np.int64)
    grids = np.meshgrid(*[np.arange(t) for t in nest.trips], indexing="ij")
    return np.stack([g.ravel() for g in grids], axis=1).astype(np.int64)


def addresses(nest: LoopNest, addr: Addr, idx: np.ndarray | None = None) -> np.ndarray:
    """The address of ``addr`` in every iteration."""
    idx = iteration_indices(nest) if idx is None else idx
    strides = np.asarray(addr.strides if addr.strides else (0,) * len(nest.trips), np.int64)
    lin = addr.offset + (idx @ strides if idx.shape[1] else np.zeros(len(idx), np.int64))
    if addr.table is None:
        return lin
    tab = np.asarray(nest.tables[addr.table], np.int64)
    if lin.min() < 0 or lin.max() >= len(tab):
        raise LoopError(f"{nest.name}: index into table {addr.table} out of range")
    return tab[lin]


def flags(nest: LoopNest, cond: Cond, idx: np.ndarray | None = None) -> np.ndarray:
    """The flag ``cond`` in every iteration (bool)."""
    idx = iteration_indices(nest) if idx is None else idx
    if cond.kind == "table":
        tab = np.asarray(nest.tables[cond.arg], np.int64)
        if len(tab) != len(idx):
            raise LoopError(f"{nest.name}: flag table {cond.arg} has {len(tab)} entries, "
                            f"the nest {len(idx)} iterations")
        return tab != 0
    lvl = int(cond.arg)
    if not 0 <= lvl < len(nest.trips):
        raise LoopError(f"{nest.name}: no loop level {lvl}")
    if cond.kind not in ("first", "last", "at_first", "at_last"):
        raise LoopError(f"{nest.name}: unknown condition {cond.kind!r}")
    upto = lvl + 1 if cond.kind.startswith("at_") else len(nest.trips)
    want = 0 if cond.kind.endswith("first") else np.asarray(nest.trips[lvl:upto],
                                                              np.int64) - 1
    return np.all(idx[:, lvl:upto] == want, axis=1)


def check_nest(nest: LoopNest) -> None:
    """Raise :class:`LoopError` for a nest that is malformed or carries a value through
    memory from one iteration to another."""
    if any(int(t) < 1 for t in nest.trips):
        raise LoopError(f"{nest.name}: trip counts must be >= 1: {nest.trips}")
    for name, tab in nest.tables.items():
        if np.asarray(tab).ndim != 1 or (len(tab) and np.min(tab) < 0):
            raise LoopError(f"{nest.name}: table {name} must hold non-negative integers")
    accs = nest.acc_names()
    defined: set = set()
    for op in nest.ops:
        if op.kind not in LOOP_KINDS:
            raise LoopError(f"{nest.name}: op kind {op.kind!r} not in {LOOP_KINDS}")
        if op.dst in defined or op.dst in accs or op.dst.startswith("c:"):
            raise LoopError(f"{nest.name}: {op.dst} defined twice")
        if op.kind == "load":
            if len(op.srcs) != 1 or op.srcs[0] not in nest.arrays or op.addr is None:
                raise LoopError(f"{nest.name}: load {op.dst} needs an array and an address")
        else:
            want = 1 if op.kind in UNARY else 2
            if len(op.srcs) != want:
                raise LoopError(f"{nest.name}: {op.kind} {op.dst} takes {want} source(s)")
            for s in op.srcs:
                if not (s in defined or s in accs or s.startswith("c:")):
                    raise LoopError(f"{nest.name}: {op.dst} reads {s} before it is defined")
        defined.add(op.dst)
    for a in nest.accs:
        if a.update not in defined or not (a.init in defined or a.init.startswith("c:")):
            raise LoopError(f"{nest.name}: accumulator {a.name} needs a defined init and "
                            "update")
    for st in nest.stores:
        if st.array not in nest.arrays or st.src not in defined:
            raise LoopError(f"{nest.name}: store of {st.src} to {st.array} is undefined")
    idx = iteration_indices(nest)
    touched: dict = {}  # (array, address) -> iterations that read or write it
    written: dict = {}
    for op in nest.ops:
        if op.kind == "load":
            _bounds(nest, op.srcs[0], a := addresses(nest, op.addr, idx))
            for n, x in enumerate(a):
                touched.setdefault((op.srcs[0], int(x)), set()).add(n)
    for st in nest.stores:
        a = addresses(nest, st.addr, idx)
        _bounds(nest, st.array, a)
        on = np.ones(len(idx), bool) if st.when is None else flags(nest, st.when, idx)
        for n in np.flatnonzero(on):
            key = (st.array, int(a[n]))
            if key in written:
                raise LoopError(f"{nest.name}: {st.array}[{key[1]}] written in iterations "
                                f"{written[key]} and {n}")
            written[key] = int(n)
    for key, n in written.items():
        others = touched.get(key, set()) - {n}
        if others:
            raise LoopError(f"{nest.name}: {key[0]}[{key[1]}] written in iteration {n} and "
                            f"read in iteration {min(others)}: carry it in an accumulator")
    for a in nest.accs:
        reset = flags(nest, a.reset, idx)
        if int(a.distance) < 1:
            raise LoopError(f"{nest.name}: accumulator {a.name} distance must be >= 1")
        if not reset[:a.distance].all():
            raise LoopError(f"{nest.name}: accumulator {a.name} is read before its first "
                            f"update (it must reset in the first {a.distance} iterations)")


def _bounds(nest, array, a):
    if len(a) and (a.min() < 0 or a.max() >= nest.arrays[array]):
        raise LoopError(f"{nest.name}: address out of range of {array} "
                        f"({nest.arrays[array]} words)")


# ------------------------------------------------------------------ bit-true executor

_K_LOAD, _K_ADD, _K_SUB, _K_MUL, _K_ACC = 0, 1, 2, 3, 4
_K_CODE = {"add": 1, "sub": 2, "mul": 3, "div": 5, "sqrt": 6, "neg": 7, "le": 8, "lt": 9}


class CompiledNest:
    """A nest lowered to integer tables for :func:`_run_kernel`: a per-iteration register
    file (constants, temporaries, accumulator values), the op table (rows: kind, dst, a, b,
    column: the array for a load or the flag column of an accumulator read), the address and
    flag of every load, store and accumulator in every iteration."""

    def __init__(self, nest: LoopNest):
        check_nest(nest)
        self.nest = nest
        idx = iteration_indices(nest)
        accs = nest.acc_names()
        arrays = list(nest.arrays)
        self.arrays = arrays
        consts = sorted({s for op in nest.ops if op.kind != "load" for s in op.srcs
                         if s.startswith("c:")} | {a.init for a in nest.accs
                                                   if a.init.startswith("c:")})
        slot: dict = {c: i for i, c in enumerate(consts)}
        for op in nest.ops:
            slot[op.dst] = len(slot)
        for a in nest.accs:
            slot[a.name] = len(slot)
        self.nregs = len(slot)
        self.init = np.zeros(self.nregs)
        for c in consts:
            self.init[slot[c]] = const_value(c)
        rows, load_cols, seen = [], [], set()
        acc_col = {a.name: k for k, a in enumerate(nest.accs)}
        for op in nest.ops:
            if op.kind == "load":
                rows.append([_K_LOAD, slot[op.dst], arrays.index(op.srcs[0]), len(load_cols)])
                load_cols.append(addresses(nest, op.addr, idx))
                continue
            for s in op.srcs:  # an accumulator's value is chosen just before its first read
                if s in accs and s not in seen:
                    seen.add(s)
                    a = accs[s]
                    rows.append([_K_ACC, slot[s], slot[a.init], acc_col[s]])
            rows.append([_K_CODE[op.kind], slot[op.dst], slot[op.srcs[0]], slot[op.srcs[-1]]])
        self.ops = np.array(rows, np.int64).reshape(-1, 4)
        n = len(idx)
        self.load_addr = np.array(load_cols, np.int64).reshape(-1, n).T.copy()
        self.acc_reset = np.array([flags(nest, a.reset, idx) for a in nest.accs],
                                  np.bool_).reshape(-1, n).T.copy()
        self.acc_slots = np.array([[slot[a.name], slot[a.update], a.distance]
                                   for a in nest.accs], np.int64).reshape(-1, 3)
        self.store = np.array([[arrays.index(s.array), slot[s.src]] for s in nest.stores],
                              np.int64).reshape(-1, 2)
        self.store_addr = np.array([addresses(nest, s.addr, idx) for s in nest.stores],
                                   np.int64).reshape(-1, n).T.copy()
        self.store_on = np.array([np.ones(n, bool) if s.when is None
                                  else flags(nest, s.when, idx) for s in nest.stores],
                                 np.bool_).reshape(-1, n).T.copy()
        self.width = max(nest.arrays.values(), default=1)


@njit(cache=True, error_model="numpy")
def _run_kernel(mem, regs, ops, load_addr, acc_reset, acc_slots, store, store_addr,
                store_on):
    dmax = 1
    for c in range(acc_slots.shape[0]):
        dmax = max(dmax, acc_slots[c, 2])
    carry = np.zeros((acc_slots.shape[0], dmax))  # ring of the last ``distance`` updates
    for n in range(load_addr.shape[0]):
        for r in range(ops.shape[0]):
            k = ops[r, 0]
            if k == 0:
                regs[ops[r, 1]] = mem[ops[r, 2], load_addr[n, ops[r, 3]]]
            elif k == 4:
                col = ops[r, 3]
                d = acc_slots[col, 2]
                regs[ops[r, 1]] = regs[ops[r, 2]] if acc_reset[n, col] else carry[col, n % d]
            else:
                a = regs[ops[r, 2]]
                b = regs[ops[r, 3]]
                if k == 1:
                    x = a + b
                elif k == 2:
                    x = a - b
                elif k == 3:
                    x = a * b
                elif k == 5:
                    x = a / b
                elif k == 6:  # sqrt(-0) = -0, sqrt(negative) = NaN
                    x = math.sqrt(a) if a >= 0.0 or a != a else (a if a == 0.0 else math.nan)
                elif k == 7:
                    x = -a
                elif k == 8:
                    x = 1.0 if a <= b else 0.0
                else:
                    x = 1.0 if a < b else 0.0
                regs[ops[r, 1]] = round_fp32(x)
        for c in range(acc_slots.shape[0]):
            carry[c, n % acc_slots[c, 2]] = regs[acc_slots[c, 1]]
        for s in range(store.shape[0]):
            if store_on[n, s]:
                mem[store[s, 0], store_addr[n, s]] = regs[store[s, 1]]


def run_nest(nest: LoopNest | CompiledNest, memories: dict) -> dict:
    """Run the nest on ``memories`` (array name -> float32 values as float64, or uint32 bit
    patterns); returns the memories after it (float64 holding float32 values), inputs
    untouched. Values are flushed to float32 on the way in (:func:`execute.to_f32`)."""
    c = nest if isinstance(nest, CompiledNest) else CompiledNest(nest)
    mem = np.zeros((len(c.arrays), c.width))
    for k, name in enumerate(c.arrays):
        v = np.asarray(memories.get(name, np.zeros(c.nest.arrays[name])))
        if v.dtype == np.uint32:
            v = v.view(np.float32)
        v = v.astype(np.float32).astype(np.float64)
        v[np.abs(v) < 2.0**-126] *= 0.0  # subnormals flushed, sign kept
        if v.shape != (c.nest.arrays[name],):
            raise LoopError(f"{c.nest.name}: memory {name} needs {c.nest.arrays[name]} words")
        mem[k, :len(v)] = v
    _run_kernel(mem, c.init.copy(), c.ops, c.load_addr, c.acc_reset, c.acc_slots, c.store,
                c.store_addr, c.store_on)
    return {name: mem[k, :c.nest.arrays[name]].copy() for k, name in enumerate(c.arrays)}


def unroll(nest: LoopNest) -> tuple[Program, dict]:
    """The nest as a straight-line :class:`Program` over registers ``<array>[<address>]``
    (for checking :func:`run_nest` against :func:`navgate.opflow.execute.run_bittrue`):
    returns (program, register name -> (array, address)). Stores become commits."""
    check_nest(nest)
    idx = iteration_indices(nest)
    prog = Program(nest.name)
    regs = {f"{a}[{i}]": (a, i) for a, words in nest.arrays.items() for i in range(words)}
    prog.registers = tuple(regs)
    cur = {r: r for r in regs}  # register -> the value it holds now (name)
    accs = nest.acc_names()
    loads = {id(op): addresses(nest, op.addr, idx) for op in nest.ops if op.kind == "load"}
    resets = {a.name: flags(nest, a.reset, idx) for a in nest.accs}
    st_addr = [addresses(nest, s.addr, idx) for s in nest.stores]
    st_on = [np.ones(len(idx), bool) if s.when is None else flags(nest, s.when, idx)
             for s in nest.stores]
    carry: dict = {}
    t = 0
    for n in range(len(idx)):
        val: dict = {}

        def name(s, val=val, n=n):
            if s.startswith("c:"):
                return s
            if s in accs:
                a = accs[s]
                return name(a.init) if resets[s][n] else carry[s][n - a.distance]
            return val[s]

        for op in nest.ops:
            if op.kind == "load":
                val[op.dst] = cur[f"{op.srcs[0]}[{loads[id(op)][n]}]"]
                continue
            t += 1
            dst = f"t{t}"
            prog.ops.append(Op(dst, op.kind, tuple(name(x) for x in op.srcs), nest.name))
            val[op.dst] = dst
        for a in nest.accs:
            carry.setdefault(a.name, {})[n] = val[a.update]
        for k, s in enumerate(nest.stores):
            if st_on[k][n]:
                cur[f"{s.array}[{st_addr[k][n]}]"] = val[s.src]
    prog.commit = {r: v for r, v in cur.items() if v != r}
    return prog, regs


# ------------------------------------------------------------------ modulo scheduling


@dataclass(frozen=True)
class LoopUnits:
    """The loop machine's resources: pipelined float32 units (mul, add, cmp), the iterative
    divider and square root (one each; an op blocks its unit for ``occupancy`` cycles) and
    memory read ports."""

    mul: int = 1
    add: int = 1
    read_ports: int = 2
    div: int = 1
    sqrt: int = 1
    cmp: int = 1
    #: cycles from a load's address to its word (2: the memory's output registered)
    load_latency: int = LOAD_LATENCY
    #: register stages between the operand multiplexers and every unit's input (0 or 1)
    operand_stage: int = 0
    #: unit results that may land in one cycle (a register file's write ports; 0: no
    #: limit, as the lane machines' delay lines): a what-if of the fast engine's brief
    result_ports: int = 0
    #: lanes as clusters, a what-if of the fast engine's brief (0: none, every unit reads
    #: every value): lane ``i`` holds mul and add ``i`` and read port ``i`` of every array
    #: (``i`` modulo the lanes), lane 0 the divider, the square root and the comparator; an
    #: op reads the values its own lane made (and constants, and the stores read any lane);
    #: a value of another lane crosses first: each lane takes at most ``transfers`` values
    #: a cycle from the others (the write ports of its transfer bank), each ready there the
    #: cycle after (:data:`TRANSFER_LATENCY`); which lane runs an op is chosen before
    #: placement (:func:`lane_plan`)
    transfers: int = 0
    #: a what-if too: after placement the loads (``"loads"``) or every op (``"all"``) move
    #: as late as their values' reads, the stores of a load's array and their units allow
    #: (:func:`_late`): the same cycles, shorter lives ("": as placed)
    late: str = ""

    @property
    def lanes(self) -> int:
        return max(self.mul, self.add)

    def latency(self, kind: str) -> int:
        if kind == "load":
            return self.load_latency
        if kind == "neg":
            return 0
        return self.operand_stage + {
            "mul": Fp32Mul.LATENCY, "add": Fp32Add.LATENCY, "sub": Fp32Add.LATENCY,
            "div": Fp32DivIter.LATENCY, "sqrt": Fp32SqrtIter.LATENCY,
            "lt": Fp32Compare.LATENCY, "le": Fp32Compare.LATENCY}[kind]

    def occupancy(self, kind: str) -> int:
        """Cycles an op blocks its unit instance (1 on a pipelined unit)."""
        return {"div": Fp32DivIter.INTERVAL, "sqrt": Fp32SqrtIter.INTERVAL}.get(kind, 1)


@dataclass
class LoopSchedule:
    nest: LoopNest
    units: LoopUnits
    ii: int
    res_mii: int
    rec_mii: int
    time: dict  #: op dst -> issue offset; stores by ("store", k)
    resource: dict  #: op dst / ("store", k) -> (resource, instance)
    ready: dict  #: op dst -> offset its value is ready
    depth: int  #: offset after an iteration's last store or result
    #: with ``units.transfers``: (value, lane) -> the offset its transfer to ``lane`` issues
    #: (ready there one cycle later); an accumulator's update read in the next iteration is
    #: keyed by the accumulator's name
    transfers: dict = field(default_factory=dict)

    @property
    def cycles(self) -> int:
        """Cycles from the first iteration's issue to the last iteration's last write."""
        return (self.nest.iterations - 1) * self.ii + self.depth


def _resource(op, units):
    if op.kind == "load":
        return ("read", op.srcs[0]), units.read_ports
    unit = UNIT_OF[op.kind]
    return (unit,), getattr(units, unit)


def modulo_schedule(nest: LoopNest, units: LoopUnits = LoopUnits(),
                    max_ii: int | None = None) -> LoopSchedule:
    """Modulo-schedule the nest's body (module docstring); raises :class:`LoopError` when no
    II up to ``max_ii`` (default: the sum of every op's latency + 8) fits."""
    check_nest(nest)
    if units.late not in ("", "loads", "all"):
        raise LoopError(f"late must be '', 'loads' or 'all', got {units.late!r}")
    accs = nest.acc_names()
    uses: dict = {}
    for op in nest.ops:
        if op.kind == "neg":
            continue
        res, count = _resource(op, units)
        if count < 1:
            raise LoopError(f"{nest.name}: no {res[0]} resource for {op.dst}")
        uses[res] = uses.get(res, 0) + units.occupancy(op.kind)
        if units.result_ports and op.kind != "load":
            uses[("result",)] = uses.get(("result",), 0) + 1
    caps = {res: _resource(next(o for o in nest.ops if o.kind != "neg"
                                and _resource(o, units)[0] == res), units)[1]
            for res in uses if res != ("result",)}
    if ("result",) in uses:
        caps[("result",)] = units.result_ports
    for st in nest.stores:
        uses[("write", st.array)] = uses.get(("write", st.array), 0) + 1
        caps[("write", st.array)] = 1
    res_mii = max([math.ceil(uses[r] / caps[r]) for r in uses] + [1])
    free = _place(nest, units, None, accs)
    rec_mii = max([math.ceil((free[2][a.update] - min(free[0][op.dst] for op in nest.ops
                                                      if a.name in op.srcs)) / a.distance)
                   for a in nest.accs if any(a.name in op.srcs for op in nest.ops)] + [1])
    start = max(res_mii, rec_mii)
    limit = max_ii or sum(units.latency(op.kind) + units.occupancy(op.kind)
                          for op in nest.ops) + len(nest.stores) + 8
    if nest.iterations == 1:  # straight line: one placement without wrap-around, II = depth
        # (the greedy placement's "II" only needs to exceed the line's length: twice the
        # bound leaves room for the transfers' delays)
        got = [g for g in (_list_place(nest, units, accs), _place(nest, units, 2 * limit, accs))
               if g is not None]
        time, resource, ready, depth, sent = min(got, key=lambda g: g[3])
        if units.late:
            _late(nest, units, None, time, resource, ready, sent)
        return LoopSchedule(nest, units, depth, res_mii, rec_mii, time, resource, ready, depth,
                            sent)
    for ii in range(start, limit + 1):
        got = _place(nest, units, ii, accs)
        if got is None:
            continue
        time, resource, ready, depth, sent = got
        if units.late:
            _late(nest, units, ii, time, resource, ready, sent)
        return LoopSchedule(nest, units, ii, res_mii, rec_mii, time, resource, ready, depth,
                            sent)
    raise LoopError(f"{nest.name}: no schedule with II <= {limit}")


def _apart(a: Addr, b: Addr) -> bool:
    """Two addresses that are the same in every iteration and differ (a load need not
    precede a store of its array to another word)."""
    return (a.table is None and b.table is None and not any(a.strides) and not any(b.strides)
            and a.offset != b.offset)


def _late(nest, units, ii, time, resource, ready, sent):
    """Move ops (last first; the loads alone when ``units.late`` is "loads") to the latest
    cycle at which their value is still ready for every read of it (its readers, an accumulator's
    reads of it, its stores, its transfers), a load one cycle before every store to its
    array that may write its word (any store of the array but one to another constant
    address), on the op's own unit instance free then for its occupancy (modulo ``ii``;
    None: a straight line); passes until nothing moves. Stores and transfers keep their
    cycles, so the schedule keeps its cycles and its rules; the values' lives shrink where
    an op made its value early. An accumulator's update stays (its next iteration's read
    would pull it, and its reader with it, later and later); with ``units.result_ports``
    only the loads move (a result's landing is a port's). In place."""
    root = _flipped(nest)
    period = ii or 1 << 30
    updates = {root(a.update) for a in nest.accs}
    movable = [op for op in reversed(nest.ops) if op.kind == "load" or (
        units.late == "all" and op.kind != "neg" and not units.result_ports
        and op.dst not in updates)]
    busy = {(resource[op.dst][0], resource[op.dst][1], (time[op.dst] + j) % period)
            for op in nest.ops if op.kind != "neg" for j in range(units.occupancy(op.kind))}
    accs = nest.acc_names()
    sites: dict = {}  # value -> (key in time or None, offset added): where it is read

    def read(x, key, extra=0):
        sites.setdefault(root(x), []).append((key, extra))

    for op in nest.ops:
        if op.kind in ("load", "neg"):
            continue
        for x in map(root, op.srcs):  # (through a sign flip, its source is read)
            if x in accs:
                a = accs[x]
                if not root(a.init).startswith("c:"):
                    read(a.init, op.dst)
                if ii is not None:
                    read(a.update, op.dst, a.distance * ii)
            elif not x.startswith("c:"):
                read(x, op.dst)
    for k, st in enumerate(nest.stores):
        read(st.src, ("store", k))
    for (key, _), t in sent.items():
        read(accs[key].update if key in accs else key, None, t)

    moved = True
    while moved:  # until nothing moves (a slot or a reader a later op left frees an earlier)
        moved = False
        for op in movable:
            if op.dst not in sites:
                continue
            deadline = min((time[key] if key is not None else 0) + extra
                           for key, extra in sites[op.dst])
            latency, occ = units.latency(op.kind), units.occupancy(op.kind)
            res, inst = resource[op.dst]
            last = max(time[op.dst], deadline - latency)
            if op.kind == "load":
                for k, st in enumerate(nest.stores):
                    if st.array == op.srcs[0] and not _apart(op.addr, st.addr):
                        last = min(last, time[("store", k)] - 1)
            mine = {(res, inst, (time[op.dst] + j) % period) for j in range(occ)}
            busy -= mine
            t = next(t for t in range(last, time[op.dst] - 1, -1) if t == time[op.dst] or not (
                {(res, inst, (t + j) % period) for j in range(occ)} & busy))
            busy |= {(res, inst, (t + j) % period) for j in range(occ)}
            moved |= t != time[op.dst]
            time[op.dst], ready[op.dst] = t, t + latency
    # a sign flip's value is its source's (one of a constant or an accumulator stays)
    for o in nest.ops:
        if o.kind == "neg" and o.srcs[0] in ready:
            time[o.dst] = ready[o.dst] = ready[o.srcs[0]]


def _flipped(nest: LoopNest):
    """A function: a name -> what it reads through sign flips (a temporary, an
    accumulator's name or a constant)."""
    alias = {op.dst: op.srcs[0] for op in nest.ops if op.kind == "neg"}

    def root(x):
        while x in alias:
            x = alias[x]
        return x

    return root


def _value_of(nest: LoopNest):
    """A function: an operand -> the temporary it reads through sign flips and an
    accumulator (its init: a straight line's, or a reset iteration's), None for a
    constant."""
    flipped, accs = _flipped(nest), nest.acc_names()

    def value(x):
        x = flipped(x)
        while x in accs:
            x = flipped(accs[x].init)
        return None if x.startswith("c:") else x

    return value


def lane_plan(nest: LoopNest, units: LoopUnits) -> dict:
    """The lane of every op for :attr:`LoopUnits.transfers` (op dst -> lane; a sign flip
    takes its source's). Ops in program order, each to the lane that made most of its
    operands (the fewest transfers; an accumulator counts as its init), ties to the lane
    with the fewest ops of its unit so far, then the lowest; the divider's, the square
    root's and the comparator's ops to lane 0. Then each load to the lane of most of its
    readers (ties: the fewest loads so far, then the lowest)."""
    lanes = units.lanes
    if units.mul != lanes or units.add != lanes or units.read_ports < lanes:
        raise LoopError(f"{nest.name}: lanes as clusters need as many multipliers, adders and "
                        f"at least as many read ports as lanes ({units})")
    accs = nest.acc_names()
    flipped, root = _flipped(nest), _value_of(nest)
    lane: dict = {}
    count: dict = {}
    readers: dict = {}  # load -> lane -> readers
    for op in nest.ops:
        if op.kind in ("load", "neg"):
            continue
        unit = UNIT_OF[op.kind]
        srcs = [x for x in map(root, op.srcs) if x is not None]
        if unit in ("mul", "add"):
            made = [lane.get(x) for x in srcs]
            choice = min(range(lanes), key=lambda k: (
                sum(m is not None and m != k for m in made), count.get((unit, k), 0), k))
        else:
            choice = 0
        lane[op.dst] = choice
        count[(unit, choice)] = count.get((unit, choice), 0) + 1
        for x in srcs:
            if x not in lane:  # a load, planned below
                readers.setdefault(x, {})
                readers[x][choice] = readers[x].get(choice, 0) + 1
    for op in nest.ops:
        if op.kind == "load":
            r = readers.get(op.dst, {})
            choice = min(range(lanes), key=lambda k: (-r.get(k, 0), count.get(("load", k), 0),
                                                      k))
            lane[op.dst] = choice
            count[("load", choice)] = count.get(("load", choice), 0) + 1
    for op in nest.ops:  # a sign flip: its source's lane (an accumulator's: its update's)
        if op.kind == "neg":
            x = flipped(op.srcs[0])
            if x in accs:
                x = flipped(accs[x].update)
            lane[op.dst] = lane.get(x, 0)
    return lane


class _Lanes:
    """The lane plan of a placement and its transfers (:attr:`LoopUnits.transfers` into
    each lane a cycle, modulo ``ii``; ``ii`` None: no resource limits, a transfer costs only
    its latency)."""

    def __init__(self, nest, units, ii, busy):
        self.units, self.ii, self.busy = units, ii, busy
        self.plan = lane_plan(nest, units)
        self.flipped, self.value = _flipped(nest), _value_of(nest)
        self.accs = nest.acc_names()
        self.sent: dict = {}  # (value, lane) -> transfer offset

    def home(self, x):
        """The lane that holds ``x`` (an accumulator's value, read through a sign flip as
        another's update: its update's lane)."""
        seen = set()
        x = self.flipped(x)
        while x in self.accs and x not in seen:
            seen.add(x)
            x = self.flipped(self.accs[x].update)
        return self.plan.get(x, 0)

    def allowed(self, dst, count):
        lane = self.plan[dst]
        return [i for i in range(count) if i % self.units.lanes == lane]

    def send(self, key, value_ready, lane, latest=None):
        """Send ``key`` (a value, or an accumulator's name) to ``lane`` on one of the lane's
        transfer ports, issued from ``value_ready`` (until ``latest`` when given): the
        offset it is ready there (that of its earlier transfer, if sent already), or None
        when no port is free."""
        if (key, lane) in self.sent:
            return self.sent[(key, lane)] + TRANSFER_LATENCY
        last = value_ready + (self.ii - 1 if self.ii else 0)
        if latest is not None:
            last = min(last, latest)
        for t in range(value_ready, last + 1):
            if self.ii is None:
                self.sent[(key, lane)] = t
                return t + TRANSFER_LATENCY
            port = next((("transfer", lane, b, t % self.ii)
                         for b in range(self.units.transfers)
                         if ("transfer", lane, b, t % self.ii) not in self.busy), None)
            if port is not None:
                self.busy.add(port)
                self.sent[(key, lane)] = t
                return t + TRANSFER_LATENCY
        return None

    def operands(self, op, ready):
        """(value, its ready offset) of every operand ``op`` reads from another lane (an
        accumulator as its init; its update, read iterations later, is checked after
        placement)."""
        out = []
        if op.kind == "load":
            return out
        for x in op.srcs:
            x = self.value(x)
            if x is not None and self.plan[x] != self.plan[op.dst]:
                out.append((x, ready[x]))
        return out


def _place(nest, units, ii, accs):
    """Greedy placement at one II (None: unlimited resources); (time, resource, ready,
    depth, transfers) or None when it does not fit."""
    time, resource, ready = {}, {}, {}
    busy: set = set()  # (resource, instance, cycle mod II)
    lanes = _Lanes(nest, units, ii, busy) if units.transfers else None

    def take(res, count, earliest, occ=1, land=None, insts=None):
        """The first cycle from ``earliest`` with an instance of ``res`` (of ``insts``
        when given) free for ``occ`` cycles (and, with ``land``, a result port free
        ``land`` cycles later)."""
        if ii is None:
            return earliest, (insts or [0])[0]
        if occ > ii:
            return None
        for t in range(earliest, earliest + ii):
            port = None
            if land is not None:
                port = _free_port(busy, units.result_ports, (t + land) % ii)
                if port is None:
                    continue
            for inst in (range(count) if insts is None else insts):
                cells = {(res, inst, (t + j) % ii) for j in range(occ)}
                if not cells & busy:
                    busy.update(cells)
                    if port is not None:
                        busy.add(port)
                    return t, inst
        return None

    for op in nest.ops:
        earliest = ADDR_READY
        if op.kind != "load":
            for s in op.srcs:
                if s.startswith("c:"):
                    continue
                if s in accs:
                    a = accs[s]
                    if not a.init.startswith("c:"):
                        earliest = max(earliest, ready[a.init])
                else:
                    earliest = max(earliest, ready[s])
        if op.kind == "neg":  # a sign flip on the consumers' operand paths: no unit, no time
            time[op.dst] = ready[op.dst] = earliest
            resource[op.dst] = None
            continue
        res, count = _resource(op, units)
        land = units.latency(op.kind) if units.result_ports and op.kind != "load" else None
        insts = None
        if lanes is not None:
            insts = lanes.allowed(op.dst, count)
            for x, r in lanes.operands(op, ready):
                arrive = lanes.send(x, r, lanes.plan[op.dst])
                if arrive is None:
                    return None
                earliest = max(earliest, arrive)
        got = take(res, count, earliest, units.occupancy(op.kind), land, insts)
        if got is None:
            return None
        time[op.dst], inst = got
        resource[op.dst] = (res, inst)
        ready[op.dst] = time[op.dst] + units.latency(op.kind)
    depth = max(ready.values(), default=ADDR_READY)
    for k, st in enumerate(nest.stores):
        earliest = max(ready[st.src], ADDR_READY)
        loads = [time[op.dst] for op in nest.ops if op.kind == "load"
                 and op.srcs[0] == st.array]
        earliest = max([earliest] + [t + 1 for t in loads])
        got = take(("write", st.array), 1, earliest)
        if got is None:
            return None
        time[("store", k)], inst = got
        resource[("store", k)] = (("write", st.array), inst)
        depth = max(depth, time[("store", k)] + 1)
    if ii is not None:
        flipped = _flipped(nest)

        def reads(op, a) -> bool:
            if lanes is None:  # as ever: a sign flip of it counts as reading it
                return a.name in op.srcs
            # with lanes, the op that reads the sign flip reads it, in its own lane
            return op.kind != "neg" and any(flipped(x) == a.name for x in op.srcs)

        for a in nest.accs:
            for op in nest.ops:
                if not reads(op, a):
                    continue
                latest = time[op.dst] + a.distance * ii  # the update's read, next iteration
                if lanes is not None and lanes.home(a.update) != lanes.plan[op.dst]:
                    got = lanes.send(a.name, ready[a.update], lanes.plan[op.dst],
                                     latest - TRANSFER_LATENCY)
                    if got is None:
                        return None
                    if got > latest:  # sent already for another reader, too late for this
                        return None
                elif ready[a.update] > latest:
                    return None
    return time, resource, ready, depth, (lanes.sent if lanes is not None else {})


def _free_port(busy: set, ports: int, cycle: int):
    """A result port free in ``cycle`` (``("result", port, cycle)``), or None."""
    return next((("result", p, cycle) for p in range(ports)
                 if ("result", p, cycle) not in busy), None)


def _sources(op, accs):
    """The temporaries ``op`` waits for (an accumulator stands for its init: a straight
    line runs one iteration, so every accumulator read is a reset)."""
    if op.kind == "load":
        return []
    out = []
    for x in op.srcs:
        if x.startswith("c:"):
            continue
        if x in accs:
            x = accs[x].init
            if x.startswith("c:"):
                continue
        out.append(x)
    return out


def schedule_beside(nest: LoopNest, line: LoopNest, units: LoopUnits = LoopUnits()) -> tuple:
    """A what-if of the fast engine's brief: the straight line ``line`` list-scheduled in
    the slots the loop nest ``nest`` (modulo-scheduled first, from cycle 0) leaves free, as
    a machine with a second sequencer would run them side by side. They must touch
    disjoint arrays (:class:`LoopError` otherwise). Returns (the nest's schedule, the
    line's schedule, the cycles of both: the later of their ends)."""
    if nest.iterations == 1 or line.iterations != 1:
        raise LoopError(f"{nest.name} beside {line.name}: a loop nest beside a straight line")
    if units.transfers or units.result_ports:
        raise LoopError("schedule_beside takes neither transfers nor result ports")
    shared = set(nest.arrays) & set(line.arrays)
    if shared:
        raise LoopError(f"{nest.name} and {line.name} share arrays {sorted(shared)}")
    looped = modulo_schedule(nest, units)
    kinds = {op.dst: op.kind for op in nest.ops}
    taken = {(got[0], got[1], k * looped.ii + looped.time[key] + j)
             for key, got in looped.resource.items() if got is not None
             for k in range(nest.iterations)
             for j in range(units.occupancy(kinds[key]) if key in kinds else 1)}
    time, resource, ready, depth, _ = _list_place(line, units, line.acc_names(), taken)
    # (the line's bounds are not computed: ResMII and RecMII 1)
    straight = LoopSchedule(line, units, depth, 1, 1, time, resource, ready, depth)
    return looped, straight, max(looped.cycles, depth)


def _list_place(nest, units, accs, taken=()):
    """A straight-line segment list-scheduled cycle by cycle with critical-path priority
    (the longest latency path from an op to the end of the segment first, ties in program
    order; as :mod:`navgate.opflow.schedule`), under the rules of :func:`_place`: units and
    read ports per cycle, the iterative units blocked for their interval, operands at their
    ready offsets, addresses and flags from ``ADDR_READY``, a store after every load of its
    array, one write port per array; ``taken``: (resource, instance, cycle) slots another
    schedule holds. Returns (time, resource, ready, depth, transfers)."""
    ops = nest.ops
    by_dst = {op.dst: k for k, op in enumerate(ops)}
    preds = [[by_dst[x] for x in _sources(op, accs)] for op in ops]
    succs: list = [[] for _ in ops]
    for k, ps in enumerate(preds):
        for p in ps:
            succs[p].append(k)
    # a store's height: the stores of its array that must follow it through the one write
    # port (ranked by the earliest cycle their word can be ready), so that on a segment bound
    # by a write port the words stored early are computed early
    free_ready = _place(nest, units, None, accs)[2]
    stored: dict = {}  # temporary -> the largest height of a store of it
    last_store: dict = {}  # array -> the largest height of a store to it
    for array in {st.array for st in nest.stores}:
        mine = sorted((free_ready[st.src], k) for k, st in enumerate(nest.stores)
                      if st.array == array)
        for rank, (_, k) in enumerate(mine):
            h = len(mine) - rank
            src = nest.stores[k].src
            stored[src] = max(stored.get(src, 0), h)
        last_store[array] = len(mine)
    height = [0] * len(ops)  # cycles from an op's issue to the end of the segment
    for k in reversed(range(len(ops))):
        op = ops[k]
        tail = max([height[c] for c in succs[k]] + [stored.get(op.dst, 0)])
        if op.kind == "load" and op.srcs[0] in last_store:
            # every store of the array waits one cycle after the load
            tail = max(tail, 1 + last_store[op.srcs[0]] - units.latency("load"))
        height[k] = units.latency(op.kind) + tail
    time, resource, ready = {}, {}, {}
    busy: set = set(taken)  # (resource, instance, cycle); ``taken``: another's slots
    waiting = [len(ps) for ps in preds]
    earliest = [ADDR_READY] * len(ops)
    queue: list = []  # (earliest, -height, index) of ops whose sources are placed
    placed = 0
    # transfers on absolute cycles (an II past any straight line's length)
    lanes = _Lanes(nest, units, 1 << 30, busy) if units.transfers else None

    def release(k):
        """``k`` has every source placed: a neg is placed at once, others queued."""
        nonlocal placed
        op = ops[k]
        if op.kind == "neg":  # a sign flip on the consumers' operand paths: no unit, no time
            time[op.dst] = ready[op.dst] = earliest[k]
            resource[op.dst] = None
            placed += 1
            done(k)
        else:
            if lanes is not None:  # operands of other lanes sent as soon as a bus is free
                for x, r in lanes.operands(op, ready):
                    earliest[k] = max(earliest[k], lanes.send(x, r, lanes.plan[op.dst]))
            heapq.heappush(queue, (earliest[k], -height[k], k))

    def done(k):
        for c in succs[k]:
            earliest[c] = max(earliest[c], ready[ops[k].dst])
            waiting[c] -= 1
            if waiting[c] == 0:
                release(c)

    for k in range(len(ops)):
        if waiting[k] == 0:
            release(k)
    cycle = ADDR_READY
    while placed < len(ops):
        now: list = []  # queued ops that may issue this cycle, by priority
        while queue and queue[0][0] <= cycle:
            _, h, k = heapq.heappop(queue)
            now.append((h, k))
        now.sort()
        later = []
        for h, k in now:
            op = ops[k]
            res, count = _resource(op, units)
            occ = units.occupancy(op.kind)
            insts = range(count) if lanes is None else lanes.allowed(op.dst, count)
            inst = next((i for i in insts if not any(
                (res, i, cycle + j) in busy for j in range(occ))), None)
            needs_port = units.result_ports and op.kind != "load"
            port = (_free_port(busy, units.result_ports, cycle + units.latency(op.kind))
                    if needs_port else None)
            if inst is None or (needs_port and port is None):
                later.append((cycle + 1, h, k))
                continue
            busy.update((res, inst, cycle + j) for j in range(occ))
            if port is not None:
                busy.add(port)
            time[op.dst] = cycle
            resource[op.dst] = (res, inst)
            ready[op.dst] = cycle + units.latency(op.kind)
            placed += 1
            done(k)
        for item in later:
            heapq.heappush(queue, item)
        if queue:  # the next cycle in which a queued op may issue
            cycle = max(cycle + 1, queue[0][0])
        elif placed < len(ops):
            raise LoopError(f"{nest.name}: ops left unplaced (a cycle in the data flow)")
    depth = max(ready.values(), default=ADDR_READY)
    order = sorted(range(len(nest.stores)), key=lambda k: (
        max([ready[nest.stores[k].src], ADDR_READY]
            + [time[op.dst] + 1 for op in ops if op.kind == "load"
               and op.srcs[0] == nest.stores[k].array]), k))
    for k in order:
        st = nest.stores[k]
        t = max([ready[st.src], ADDR_READY] + [time[op.dst] + 1 for op in ops
                                               if op.kind == "load" and op.srcs[0] == st.array])
        while (("write", st.array), 0, t) in busy:
            t += 1
        busy.add((("write", st.array), 0, t))
        time[("store", k)] = t
        resource[("store", k)] = (("write", st.array), 0)
        depth = max(depth, t + 1)
    return time, resource, ready, depth, (lanes.sent if lanes is not None else {})
