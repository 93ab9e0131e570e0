"""The register machine: a sequence program (:class:`~navgate.opflow.sequence.SequenceProgram`)
run one instruction per cycle on ONE float32 multiplier, adder, iterative divider, iterative
square root and comparator, its values in a register file and a data memory addressed by
the instructions: the smallest machine of opflow's programs.

Reference: the loop-nest IR and executor of :mod:`navgate.opflow.loops` and the sequence
programs of :mod:`navgate.opflow.sequence`, whose :func:`~navgate.opflow.sequence.run_sequence`
defines the results; list scheduling as :mod:`navgate.opflow.schedule`; the organisation of a
microcoded DSP (load/store over a register file, zero-overhead loops, table-indirect
addressing). docs/opflow-register-machine.md describes it and gives its figures.

Why: the lane machines (:mod:`navgate.opflow.sequence`) pass every value through a delay line
and hold one control row per cycle, which costs logic in proportion to the program's cycles.
Where the time budget is loose (a navigation filter's sample period is hundreds of
thousands of cycles), a machine that issues one op per cycle and keeps its values in
memories does the work in a fraction of the period with a fraction of the logic.

Program form (:func:`compile_program`)
--------------------------------------
Every segment of the sequence program becomes a **block**: instruction rows run once per
iteration, iterations one after another (a block's rows drain every write of an iteration
before the next starts), ``trips`` the nest's iteration count (1 for a straight-line
segment); or, for a nest named in ``overlap``, a **software pipeline**: a kernel of II
cycles of rows that starts an iteration every II cycles, each row predicated on its
iteration (:meth:`_Compiler.modulo_schedule`, docs/opflow-register-machine.md section 8).
An entry runs its blocks in order.

* **Memories.** Arrays that only straight-line segments touch (the register array of
  programs' scalar registers) live in the **register file** beside the constants, the
  temporaries and the accumulators; every other array is a region of the **data memory**
  (block RAM, one read port for loads, one write port for stores). A load from a
  register-file array is the register itself; a store to one is a ``mov``.
* **Addresses.** Every load and store address of a nest is materialised for every
  iteration (:func:`~navgate.opflow.loops.addresses`): constant, ``base + n`` (n the
  iteration number), or ``base + table[tb + n]`` from the **table ROM** (9-bit entries,
  identical tables stored once); a store's ``when`` flag is folded into its table (entry
  :data:`SKIP`: no write), an accumulator's reset into a conditional ``mov`` from its init.
* **Accumulators.** An iteration sees every write of the one before it (a software
  pipeline's loop-carried constraints keep this), so an accumulator is one register: reset
  by a conditional ``mov acc <- init`` at the start of the iteration, updated by ``mov acc
  <- update`` after its last read. A nest whose accumulators have distance d > 1 (sums
  interleaved for a pipelined machine) is first permuted so that each sum's iterations are
  consecutive (:func:`serialize_chains`): every sum keeps its terms' order, so the results
  are the same bits.
* **neg** is a sign flip on an operand path (``na``/``nb``); a flipped value stored or
  committed goes through a ``mov`` with the flip (NaN in: the canonical NaN out, as
  :func:`~navgate.numerics.fp32.fp32_neg`).

Timing (issue cycle ``c``: the row is in the instruction register, fetched the cycle before
from the ROM; a ``nop k`` holds it ``k`` cycles): register reads are presented in ``c``
(synchronous, data in ``c + 1``), so are the table ROM reads; the operands are flipped and
registered in ``c + 1``, a unit takes them in ``c + 2`` and its result is written to the
register file in ``c + 2 + L`` (``L`` its ``LATENCY``), read by a row issued from
``c + 3 + L``; the data address is registered in ``c + 1``, a load reads the data memory
in ``c + 2`` and writes the register in ``c + 3``, a store writes the data memory in
``c + 2``; a ``mov`` writes its register in ``c + 2``. One register write per cycle (the
scheduler books the write port), the divider and square root ``INTERVAL`` apart. Rows are
list-scheduled by critical path (as :mod:`navgate.opflow.schedule`); idle cycles become
``nop k`` rows (one row for ``k`` cycles), so the instruction ROM grows with the ops, not
the cycles.

Instruction word (:data:`INSTR_BITS` = 36 bits, one block-RAM word): ``kind`` [0:4];
ops: ``dst`` [4:12], ``a`` [12:20], ``na`` [20], ``b`` [21:29], ``nb`` [29]; ``mov``:
``dst``, ``a``, ``na``, ``mode`` [22:24], ``tb`` [24:36]; ``load``: ``dst``, ``base``
[12:22], ``mode``, ``tb``; ``store``: the source register in [4:12], ``base``, ``mode``,
``tb``; ``nop``: ``count`` [12:28].
"""

from __future__ import annotations

import heapq
import random
from dataclasses import dataclass, field

import numpy as np
from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware.fp32 import Fp32Add, Fp32Compare, Fp32DivIter, Fp32Mul, Fp32SqrtIter
from navgate.numerics import fp32 as F
from navgate.opflow.ir import const_value
from navgate.opflow.loopmachine import simulate_entries
from navgate.opflow.loops import (
    LoopError,
    LoopNest,
    addresses,
    check_nest,
    flags,
)
from navgate.opflow.sequence import ONE as ONE_BITS
from navgate.opflow.sequence import SequenceProgram, _bits, _neg, check_sequence

__all__ = ["RegisterProgram", "Block", "Row", "compile_program", "run_register_program",
           "serialize_chains", "RegisterMachine", "simulate_register_machine", "SKIP",
           "INSTR_BITS", "KIND_CODE"]

#: a table entry meaning "no access in this iteration" (a store's ``when`` false, an
#: accumulator kept)
SKIP = 511
TABLE_BITS = 9
INSTR_BITS = 36
REG_BITS = 8
BASE_BITS = 10
TB_BITS = 12
COUNT_BITS = 16
KIND_CODE = {"nop": 0, "add": 1, "sub": 2, "mul": 3, "div": 4, "sqrt": 5, "lt": 6, "le": 7,
             "load": 8, "store": 9, "mov": 10}
#: addressing modes of load, store, mov
M_CONST, M_LINEAR, M_TABLE = 0, 1, 2
UNIT_OF = {"add": "add", "sub": "add", "mul": "mul", "div": "div", "sqrt": "sqrt",
           "lt": "cmp", "le": "cmp"}
UNIT_CLASS = {"add": Fp32Add, "mul": Fp32Mul, "div": Fp32DivIter, "sqrt": Fp32SqrtIter,
              "cmp": Fp32Compare}
LATENCY = {u: c.LATENCY for u, c in UNIT_CLASS.items()}
#: cycles between two issues to a non-pipelined unit
INTERVAL = {"div": Fp32DivIter.INTERVAL, "sqrt": Fp32SqrtIter.INTERVAL}


#: cycles from issue to a store's data-memory write (the address is registered once)
STORE_WRITE = 2


def write_delay(kind: str) -> int:
    """Cycles from issue to the register write of an instruction of ``kind``: a unit takes
    its operands from a register stage in ``c + 2``; a load reads the data memory in
    ``c + 2`` (its address registered); a mov writes in ``c + 2`` (its word and its
    table flag registered)."""
    if kind in UNIT_OF:
        return 2 + LATENCY[UNIT_OF[kind]]
    return {"load": 3, "mov": 2}[kind]


# ------------------------------------------------------------------ program form


@dataclass
class Row:
    """One instruction row: ``kind``, its fields (see the module docstring), ``cycles``
    it occupies (``nop`` rows more than one)."""

    kind: str
    dst: int = 0
    a: int = 0
    na: int = 0
    b: int = 0
    nb: int = 0
    mode: int = 0
    base: int = 0
    tb: int = 0
    count: int = 1
    #: the row's stage times n's step in an overlapped block (kept beside the word, not in
    #: it): the row works on the iteration ``n - back`` of the kernel iteration ``n``
    back: int = 0

    def word(self) -> int:
        for name, bits in (("dst", REG_BITS), ("a", REG_BITS), ("b", REG_BITS), ("na", 1),
                           ("nb", 1), ("mode", 2), ("base", BASE_BITS), ("tb", TB_BITS),
                           ("count", COUNT_BITS)):
            if not 0 <= getattr(self, name) < 1 << bits:
                raise LoopError(f"{self.kind} row: {name} {getattr(self, name)} does not fit "
                                f"its {bits} bits")
        k = KIND_CODE[self.kind]
        if self.kind == "nop":
            return k | (self.count << 12)
        if self.kind in UNIT_OF:
            return (k | self.dst << 4 | self.a << 12 | self.na << 20 | self.b << 21
                    | self.nb << 29)
        if self.kind == "mov":
            return (k | self.dst << 4 | self.a << 12 | self.na << 20 | self.mode << 22
                    | self.tb << 24)
        if self.kind == "load":
            return k | self.dst << 4 | self.base << 12 | self.mode << 22 | self.tb << 24
        if self.kind == "store":
            return k | self.a << 4 | self.base << 12 | self.mode << 22 | self.tb << 24
        raise LoopError(f"unknown row kind {self.kind!r}")


@dataclass
class Block:
    """A block: ``rows`` run ``trips`` times (``cycles`` each), then the rows after
    ``kernel_rows`` once (``tail`` cycles: an overlapped block's drain). A block that is
    not overlapped has ``kernel_rows = len(rows)``, ``tail = 0`` and ``valid_trips =
    trips``. An overlapped (software-pipelined) block's rows are its kernel: ``cycles`` is
    its initiation interval II, a row of stage s works on iteration k - s in kernel
    iteration k (``Row.back`` = s * step) and issues only when 0 <= k - s < ``valid_trips``,
    so the ``trips = valid_trips + stages - 1`` kernel iterations hold the prologue and the
    epilogue."""

    name: str
    trips: int
    rows: list  #: of Row
    cycles: int  #: cycles of one iteration (the rows' cycles)
    ops: int = 0  #: issuing rows (not nop)
    step: int = 1  #: n's step per iteration (the copies of an unrolled nest)
    kernel_rows: int | None = None  #: rows repeated (default: all)
    tail: int = 0  #: cycles of the rows after the kernel, run once
    valid_trips: int | None = None  #: iterations of the nest's blocks (default: trips)
    stages: int = 1  #: an overlapped block's stages (iterations in flight)
    overlapped: bool = False  #: software-pipelined (writes may land in later iterations)

    @property
    def run_cycles(self) -> int:
        """Cycles of one run of the block: its kernel ``trips`` times, then the tail."""
        return self.trips * self.cycles + self.tail

    def __post_init__(self):
        if self.kernel_rows is None:
            self.kernel_rows = len(self.rows)
        if self.valid_trips is None:
            self.valid_trips = self.trips


@dataclass
class RegisterProgram:
    """A sequence program compiled for the register machine."""

    program: SequenceProgram
    blocks: dict  #: segment name -> Block
    entries: dict  #: entry -> tuple of block names
    reg_arrays: dict  #: array -> first register
    data_arrays: dict  #: array -> base address in the data memory
    constants: dict  #: constant name -> register
    registers: int  #: registers used
    reg_init: list  #: register -> uint32 word (constants; zeros elsewhere)
    table: list  #: table ROM entries
    data_words: int
    data_init: list = field(default_factory=list)  #: data memory words at configuration
    #: register -> word: the accumulators re-armed at the end of their nests, which the
    #: machine writes again after every reset
    acc_restore: dict = field(default_factory=dict)

    def cycles(self, entry: str) -> int:
        """Cycles from the start cycle to ``done`` (exact; the machine's)."""
        return 2 + sum(self.blocks[b].run_cycles for b in self.entries[entry])

    def host_address(self, array: str, word: int) -> int:
        """The machine's host-port address of ``array[word]`` (:class:`RegisterMachine`)."""
        if array in self.reg_arrays:
            return (1 << BASE_BITS) | (self.reg_arrays[array] + word)
        return self.data_arrays[array] + word

    def layout(self):
        """The instruction ROM words (identical blocks stored once), block -> (first row,
        last row of the kernel, last row), the steps (for each entry its blocks as (first
        row, last row of the kernel, n of the last kernel iteration, last of the entry,
        n's step, last row, n of the last valid iteration)), entry -> its first step, and
        each ROM row's ``back`` (:class:`Row`)."""
        words: list = []
        backs: list = []
        at: dict = {}
        where: dict = {}
        for name, blk in self.blocks.items():
            key = tuple((r.word(), r.back) for r in blk.rows)
            if key not in at:
                at[key] = len(words)
                words.extend(w for w, _ in key)
                backs.extend(b for _, b in key)
            where[name] = (at[key], at[key] + blk.kernel_rows - 1, at[key] + len(blk.rows) - 1)
        steps, first = [], {}
        for e, blocks in self.entries.items():
            first[e] = len(steps)
            for k, b in enumerate(blocks):
                blk = self.blocks[b]
                f, kl, tl = where[b]
                steps.append((f, kl, (blk.trips - 1) * blk.step, int(k == len(blocks) - 1),
                              blk.step, tl, (blk.valid_trips - 1) * blk.step))
        return words, where, steps, first, backs


#: item orders the modulo scheduler tries at the lowest II its cycle bound allows (the
#: height order, then perturbed heights) before it moves to the next II, where it tries the
#: height order alone
ORDER_TRIES = 32


def _positive_cycle(n: int, edges) -> bool:
    """Whether the constraints t_b >= t_a + d (``edges`` (a, b, d)) have a cycle of
    positive total delay, i.e. no solution at all (Bellman-Ford on the longest path)."""
    dist = [0] * n
    for _ in range(max(n, 1)):
        changed = False
        for a, b, d in edges:
            if dist[a] + d > dist[b]:
                dist[b] = dist[a] + d
                changed = True
        if not changed:
            return False
    return True


def _dependences(items, store_height: int):
    """A block's edges: per item its predecessors and successors as (item, min cycles
    between the issues; a data edge waits for the write to land), and its height, the
    longest latency-weighted path from its issue to the block's end (a store's own
    ``store_height``)."""
    n = len(items)
    ready = [None if it.kind == "store" else write_delay(it.kind) + 1 for it in items]
    preds = [[] for _ in range(n)]
    for k, it in enumerate(items):
        for j, d in it.after:
            preds[k].append((j, ready[j] if d is None else d))
    succs = [[] for _ in range(n)]
    for k in range(n):
        for j, d in preds[k]:
            succs[j].append((k, d))
    height = [0] * n
    for k in reversed(range(n)):
        own = ready[k] if ready[k] is not None else store_height
        height[k] = max([own] + [d + height[s] for s, d in succs[k]])
    return preds, succs, height


def _lives(items, issue, fixed):
    """(landing cycle, last read or None, name) of every temporary a block's items write
    (not the fixed registers)."""
    last_read: dict = {}
    for k, it in enumerate(items):
        for s in it.srcs:
            last_read[s] = max(last_read.get(s, -1), issue[k])
    return [(issue[k] + write_delay(it.kind), last_read.get(it.dst), it.dst)
            for k, it in enumerate(items) if _temporary(it, fixed)]


def _temporary(it, fixed) -> bool:
    """Whether ``it`` writes a temporary (not a fixed register)."""
    return it.dst is not None and it.fixed_dst is None and it.dst not in fixed


# ------------------------------------------------------------------ chains


def serialize_chains(nest: LoopNest) -> np.ndarray:
    """The iteration order that makes every accumulator chain consecutive: returns ``perm``
    (new position -> original iteration). With accumulators of distance ``d``, iteration n
    continues the chain of n - d unless its reset flag holds; in ``perm`` each chain's
    iterations follow one another in their order, chains ordered by their first iteration.
    All accumulators must share distance and reset pattern (LoopError otherwise)."""
    n_it = nest.iterations
    if all(a.distance == 1 for a in nest.accs):  # every chain already consecutive
        return np.arange(n_it)
    d = nest.accs[0].distance
    reset = flags(nest, nest.accs[0].reset)
    for a in nest.accs[1:]:
        if a.distance != d or not np.array_equal(flags(nest, a.reset), reset):
            raise LoopError(f"{nest.name}: the register machine needs every accumulator of a "
                            "nest on one chain structure (same distance and reset)")
    succ = {}
    for n in range(n_it):
        if not reset[n]:
            succ[n - d] = n
    perm = []
    for n in range(n_it):
        if reset[n]:
            k = n
            while True:
                perm.append(k)
                if k not in succ:
                    break
                k = succ[k]
    if sorted(perm) != list(range(n_it)):
        raise LoopError(f"{nest.name}: accumulator chains do not cover the iterations once")
    return np.asarray(perm)


# ------------------------------------------------------------------ lowering


@dataclass
class _Item:
    """One instruction before scheduling."""

    kind: str
    dst: str | None = None  #: value written (a temporary, or a fixed register's name)
    srcs: tuple = ()  #: value names read
    neg: tuple = ()  #: flip bits of srcs
    mode: int = M_CONST
    base: int = 0
    table: tuple | None = None  #: materialised table entries (mode M_TABLE)
    after: list = field(default_factory=list)  #: (item index, min cycles after its issue)
    fixed_dst: int | None = None  #: a register (register-file array word, accumulator)


class _Compiler:
    def __init__(self, prog: SequenceProgram, reg_arrays, max_registers: int,
                 overlap=()):
        self.prog = prog
        self.overlap = frozenset(overlap)
        self.reg_arrays = {}
        nreg = 0
        for a in reg_arrays:
            self.reg_arrays[a] = nreg
            nreg += prog.arrays[a]
        self.data_arrays = {}
        base = 0
        for a, w in prog.arrays.items():
            if a not in self.reg_arrays:
                self.data_arrays[a] = base
                base += w
        if base > 1 << BASE_BITS:
            raise LoopError(f"{prog.name}: {base} data words; the machine addresses "
                            f"{1 << BASE_BITS}")
        self.data_words = base
        self.constants: dict = {}
        self.nfixed = nreg
        self.max_registers = max_registers
        self.table: list = []
        self.table_at: dict = {}
        self.acc_regs: dict = {}
        self.acc_init: dict = {}  #: accumulator register -> constant it starts from

    def constant(self, name: str) -> int:
        if name not in self.constants:
            self.constants[name] = self.nfixed
            self.nfixed += 1
        return self.constants[name]

    def put_table(self, entries) -> int:
        key = tuple(int(x) for x in entries)
        if key and (min(key) < 0 or max(key) > SKIP):
            raise LoopError(f"{self.prog.name}: a table entry outside 0..{SKIP}")
        if key not in self.table_at:
            # an identical run already stored (e.g. a prefix) is not searched for: tables
            # are stored whole, identical ones once
            self.table_at[key] = len(self.table)
            self.table.extend(key)
            if len(self.table) > 1 << TB_BITS:
                raise LoopError(f"{self.prog.name}: table ROM over {1 << TB_BITS} entries")
        return self.table_at[key]

    # -- one nest -> items
    def lower(self, sname: str, nest: LoopNest, copies: int = 1):
        """``nest`` -> (items, fixed registers, block trips, step of n). With ``copies`` > 1,
        that many consecutive iterations in one block iteration (copy ``u`` of block
        iteration ``k`` is iteration ``k * copies + u``; n steps by ``copies``, so a table
        serves every copy at offset ``u`` and ``base + n`` stays linear); an accumulator of
        distance ``copies`` (sums interleaved over that many tracks) is then one register per
        copy, continued by that copy in the next block iteration."""
        check_nest(nest)
        n_full = nest.iterations
        if copies < 1 or n_full % copies:
            raise LoopError(f"{sname}: {n_full} iterations do not divide into {copies} copies")
        if copies > 1 and any(a.distance != copies for a in nest.accs):
            raise LoopError(f"{sname}: {copies} copies need accumulators of distance "
                            f"{copies}")
        perm = np.arange(n_full) if copies > 1 else serialize_chains(nest)
        n_it = n_full // copies
        items: list = []
        producer: dict = {}  # value -> item index
        flip_of: dict = {}  # value -> (source value, flip) for neg chains and aliases
        fixed: dict = {}  # value -> register (register-array words, constants, accumulators)
        reg_readers: dict = {}  # fixed register -> reader item indices

        def addr_mode(array, addr, u):
            a_full = addresses(nest, addr)[perm]
            a = a_full[u::copies]
            if array in self.reg_arrays:
                if len(set(a_full.tolist())) != 1:
                    raise LoopError(f"{sname}: register-file array {array} needs constant "
                                    "addresses")
                return ("reg", self.reg_arrays[array] + int(a[0]))
            base = self.data_arrays[array]
            if len(set(a.tolist())) == 1:
                return (M_CONST, base + int(a[0]), None)
            if np.array_equal(a_full, a_full[0] + np.arange(n_full)):
                return (M_LINEAR, base + int(a_full[0]) + u, None)
            if a_full.max() >= SKIP:
                raise LoopError(f"{sname}: {array} addresses up to {a_full.max()}: table "
                                f"entries hold at most {SKIP - 1}")
            return (M_TABLE, base, (tuple(a_full.tolist()), u))

        def resolve(v):
            flip = 0
            while v in flip_of:
                v, f = flip_of[v]
                flip ^= f
            return v, flip

        def canonical(v, f, src, rn):
            """A stored value negated an even number of times: fp32_neg twice turns a NaN
            into the canonical NaN, so it is moved through two flips (a word never negated
            is stored as it is)."""
            if f or rn(src) not in flip_of:
                return v, f
            tmp = f"{v}__neg2_{len(items)}"
            add(_Item("mov", dst=tmp, srcs=(v,), neg=(1,)))
            return tmp, 1

        def value(v):
            """-> (value name, flip); constants get their registers."""
            v, f = resolve(v)
            if v.startswith("c:"):
                fixed[v] = self.constant(v)
            return v, f

        def add(it: _Item) -> int:
            items.append(it)
            k = len(items) - 1
            for s in it.srcs:
                if s in producer:
                    it.after.append((producer[s], None))  # data edge (latency filled later)
                if s in fixed:
                    reg_readers.setdefault(fixed[s], []).append(k)
            if it.dst is not None:
                producer[it.dst] = k
            return k

        resets_full = {a.name: flags(nest, a.reset)[perm] for a in nest.accs}
        on_full = [np.ones(n_full, bool) if st.when is None else flags(nest, st.when)[perm]
                   for st in nest.stores]
        for u in range(copies):
            def rn(x, u=u):
                return x if copies == 1 or x.startswith("c:") else f"{x}@{u}"

            acc_mov: dict = {}
            for a in nest.accs:
                key = (sname, rn(a.name))
                if key not in self.acc_regs:
                    self.acc_regs[key] = self.nfixed
                    self.nfixed += 1
                fixed[rn(a.name)] = self.acc_regs[key]
            pending_resets = {rn(a.name): a for a in nest.accs}

            def emit_reset(a, u=u, rn=rn, acc_mov=acc_mov, pending_resets=pending_resets):
                r_full = resets_full[a.name]
                init, f = value(rn(a.init))
                if r_full[u::copies].all():
                    mode, tab = M_CONST, None
                else:
                    mode, tab = M_TABLE, (tuple(0 if x else SKIP for x in r_full), u)
                k = add(_Item("mov", dst=rn(a.name), srcs=(init,), neg=(f,), mode=mode,
                              table=tab, fixed_dst=fixed[rn(a.name)]))
                acc_mov[rn(a.name)] = k
                del pending_resets[rn(a.name)]

            # a constant init whose reset follows exactly the iterations after a
            # conditional store's (a chained sum: the sum is stored, the next one starts) is
            # re-armed at the END of the storing iteration by a mov on the store's own
            # table, and after the last iteration too: the register then holds init
            # whenever the nest starts (its initial value, and what every run leaves), and
            # no reset table is stored
            late: dict = {}  # acc -> store index
            for a in list(pending_resets.values()):
                if not a.init.startswith("c:"):
                    continue
                rearm = np.append(resets_full[a.name][u::copies][1:], True)
                hit = [i for i, on in enumerate(on_full) if not on[u::copies].all()
                       and np.array_equal(on[u::copies], rearm)]
                if hit:
                    late[rn(a.name)] = hit[0]
                    self.acc_init[fixed[rn(a.name)]] = a.init
                    value(a.init)
                    acc_mov[rn(a.name)] = None
                    del pending_resets[rn(a.name)]
                else:
                    emit_reset(a)
            for op in nest.ops:
                if op.kind == "load":
                    m = addr_mode(op.srcs[0], op.addr, u)
                    if m[0] == "reg":
                        fixed[rn(op.dst)] = m[1]
                        continue
                    add(_Item("load", dst=rn(op.dst), mode=m[0], base=m[1], table=m[2]))
                    continue
                if op.kind == "neg":
                    flip_of[rn(op.dst)] = (rn(op.srcs[0]), 1)
                    continue
                srcs, negs = [], []
                for s in op.srcs:
                    if rn(s) in pending_resets:
                        raise LoopError(f"{sname}: accumulator {s} read before its init is "
                                        "ready")
                    v, f = value(rn(s))
                    srcs.append(v)
                    negs.append(f)
                k = add(_Item(op.kind, dst=rn(op.dst), srcs=tuple(srcs), neg=tuple(negs)))
                for s in srcs:
                    if acc_mov.get(s) is not None:
                        items[k].after.append((acc_mov[s], 2))
                for a in list(pending_resets.values()):
                    if a.init == op.dst:
                        emit_reset(a)
            # accumulator updates: mov acc <- update after every read of acc
            update_mov = {}
            for a in nest.accs:
                upd, f = value(rn(a.update))
                k = add(_Item("mov", dst=None, srcs=(upd,), neg=(f,),
                              fixed_dst=fixed[rn(a.name)]))
                update_mov[rn(a.name)] = k
                for r in reg_readers.get(fixed[rn(a.name)], []):
                    if r != k:
                        items[k].after.append((r, 1))
            store_items = {}
            commits: list = []
            # registers this segment commits: a commit whose source is one of them reads a
            # copy made first (a rotation of words would otherwise wait on itself)
            modes = [addr_mode(st.array, st.addr, u) for st in nest.stores]
            targets = {m[1] for m in modes if m[0] == "reg"}
            for si, st in enumerate(nest.stores):
                v, f = value(rn(st.src))
                m = modes[si]
                on = on_full[si]
                if m[0] == "reg":
                    if not on.all():
                        raise LoopError(f"{sname}: conditional store to register-file array "
                                        f"{st.array}")
                    reg = m[1]
                    v, f = canonical(v, f, st.src, rn)
                    if fixed.get(v) in targets:
                        tmp = f"{v}__copy_{len(items)}"
                        add(_Item("mov", dst=tmp, srcs=(v,), neg=(0,)))
                        v = tmp
                    commits.append((add(_Item("mov", srcs=(v,), neg=(f,), fixed_dst=reg)),
                                    reg))
                    continue
                v, f = canonical(v, f, st.src, rn)
                if f:  # a flipped value is stored through a mov with the flip
                    tmp = f"{v}__neg_{len(items)}"
                    add(_Item("mov", dst=tmp, srcs=(v,), neg=(1,)))
                    v = tmp
                mode, base, tab = m
                if not on[u::copies].all():
                    rel = addresses(nest, st.addr)[perm]
                    # (a store that never fires is all SKIP)
                    if on.any() and rel[on].max() >= SKIP:
                        raise LoopError(f"{sname}: conditional store to {st.array} up to word "
                                        f"{rel[on].max()}: table entries hold at most "
                                        f"{SKIP - 1}")
                    base = self.data_arrays[st.array]
                    tab = (tuple(int(x) if o else SKIP for x, o in zip(rel, on, strict=True)),
                           u)
                    mode = M_TABLE
                k = add(_Item("store", srcs=(v,), neg=(0,), mode=mode, base=base, table=tab))
                store_items[si] = k
                # a store follows every load of its array (reads see the words at the start)
                lo, hi = self.data_arrays[st.array], self.data_arrays[st.array] + \
                    self.prog.arrays[st.array]
                for j, it in enumerate(items[:k]):
                    if it.kind == "load" and lo <= it.base < hi:
                        items[k].after.append((j, 1))
            # a commit to a register-file word follows EVERY read of that word in the
            # segment (reads see the words at the start), the reads of later stores included
            for k, reg in commits:
                for r in reg_readers.get(reg, []):
                    if r != k:
                        items[k].after.append((r, 1))
            for name, si in late.items():  # re-arm after the update, on the store's table
                st_item = items[store_items[si]]
                init, _ = value(self.acc_init[fixed[name]])
                k = add(_Item("mov", srcs=(init,), neg=(0,), mode=M_TABLE,
                              table=st_item.table, fixed_dst=fixed[name]))
                items[k].after.append((update_mov[name], 1))
        return items, fixed, n_it, copies

    # -- schedule one block
    def schedule(self, sname: str, items: list):
        n = len(items)
        # priority: longest path to the end (latency-weighted)
        preds, succs, height = _dependences(items, store_height=2)
        issue = [None] * n
        earliest = [0] * n
        npred = [len(p) for p in preds]
        ready = [k for k in range(n) if npred[k] == 0]
        writes: set = set()
        unit_busy: dict = {}
        c = 0
        done = 0
        while done < n:
            best = None
            for k in ready:
                if earliest[k] > c:
                    continue
                it = items[k]
                if it.kind != "store":
                    w = c + write_delay(it.kind)
                    if w in writes:
                        continue
                u = UNIT_OF.get(it.kind)
                if u in INTERVAL and unit_busy.get(u, -10**9) + INTERVAL[u] > c:
                    continue
                if best is None or (height[k], -k) > (height[best], -best):
                    best = k
            if best is not None:
                it = items[best]
                issue[best] = c
                if it.kind != "store":
                    writes.add(c + write_delay(it.kind))
                u = UNIT_OF.get(it.kind)
                if u in INTERVAL:
                    unit_busy[u] = c
                ready.remove(best)
                done += 1
                for s, d in succs[best]:
                    earliest[s] = max(earliest[s], c + d)
                    npred[s] -= 1
                    if npred[s] == 0:
                        ready.append(s)
            c += 1
            if c > 10**6:
                raise LoopError(f"{sname}: scheduling did not converge")
        end = 0
        for k, it in enumerate(items):
            if it.kind == "store":
                end = max(end, issue[k] + STORE_WRITE + 1)
            else:
                end = max(end, issue[k] + write_delay(it.kind) + 1)
        return issue, max(end, 1)

    # -- an overlapped block: modulo schedule
    def modulo_schedule(self, sname: str, items: list, fixed: dict, trips: int,
                        bound: int):
        """Software-pipeline a nest's block iteration (iterative modulo scheduling, Rau
        1994, in its simplest greedy form): one block iteration starts every II cycles;
        an item's offset ``t`` puts it in kernel row ``t mod II`` and stage ``t // II``.
        Per cycle modulo II: one issue, one register write (at ``t + write_delay``), the
        divider and the square root busy ``INTERVAL`` cycles from their issues. Between
        iterations only the fixed registers a block writes (accumulators) carry values
        (:func:`~navgate.opflow.loops.check_nest` refuses values carried through memory):
        for every writer W and reader R of one, iteration k + 1's R reads after iteration
        k's W lands, iteration k + 1's W lands no earlier than iteration k's R reads, and
        writes land in iteration order. A temporary lives at most II cycles (from its
        landing to its last read), so every iteration's temporaries can share the kernel's
        registers. II starts at the resource bound and grows while a longer II can still
        give a cheaper block ((trips + stages - 1) x II + tail) and stay under ``bound``
        cycles a run; each II is placed by :meth:`_modulo_place` (placement with
        eviction, then compaction), and the cheapest block whose registers fit the
        machine is kept. Returns (offsets, II, stages, depth) with depth the offset after
        the last write lands; LoopError when no II under the bound fits."""
        n = len(items)
        wd = [None if it.kind == "store" else write_delay(it.kind) for it in items]
        preds, _, height = _dependences(items, store_height=STORE_WRITE + 1)
        # loop-carried constraints on the fixed registers the block writes: (a, b, lat):
        # t_b + II >= t_a + lat (b in the next iteration)
        writers: dict = {}
        for k, it in enumerate(items):
            if it.fixed_dst is not None:
                writers.setdefault(it.fixed_dst, []).append(k)
        carried = []
        for k, it in enumerate(items):
            for s in it.srcs:
                reg = fixed.get(s)
                for w in writers.get(reg, ()) if reg is not None else ():
                    carried.append((w, k, wd[w] + 1))  # RAW
                    carried.append((k, w, -wd[w]))  # WAR: lands at or after the read
        for ws in writers.values():
            for w in ws:
                for w2 in ws:
                    if w != w2:
                        carried.append((w, w2, wd[w] + 1 - wd[w2]))  # WAW
        # a temporary lives at most II cycles: its reader k at most II after it lands
        lifetime = [(k, j, wd[j]) for k, it in enumerate(items) for j, d in it.after
                    if d is None and _temporary(items[j], fixed)]
        writes = sum(w is not None for w in wd)
        mii = max(n, writes, 1)
        for u in INTERVAL:
            uses = sum(UNIT_OF.get(it.kind) == u for it in items)
            mii = max(mii, uses * INTERVAL[u])
        intra = [(j, k, d) for k in range(n) for j, d in preds[k]]
        best = None
        tried_orders = False
        for ii in range(mii, bound // max(trips - 1, 1) + 2):
            if (trips - 1) * ii >= min(bound, best[0] if best else bound):
                break  # no longer II can beat the best block found, or the bound
            edges = (intra + [(a, b, lat - ii) for a, b, lat in carried]
                     + [(k, j, -w - ii) for k, j, w in lifetime])
            if _positive_cycle(n, edges):
                continue  # below the recurrence (and lifetime) bound: no order can fit
            # the height order first; at the first II above the cycle bound, orders with
            # the heights perturbed too (seeded: the program is the same on every run)
            # until one fits
            rnd = random.Random(ii)
            tries = 1 if tried_orders else ORDER_TRIES
            tried_orders = True
            for trial in range(tries):
                h = height if trial == 0 else [x + 3 * rnd.random() for x in height]
                t = self._modulo_place(items, ii, wd, h, 40 * n + 100, edges)
                if t is not None and all(t[b] >= t[a] + d for a, b, d in edges):
                    break
            else:
                continue
            base = min(t)
            t = [x - base for x in t]
            depth = max((t[k] + (wd[k] if wd[k] is not None else STORE_WRITE) + 1)
                        for k in range(n))
            stages = max(t) // ii + 1
            cost = (trips + stages - 1) * ii + max(0, depth - stages * ii)
            if best is not None and cost >= best[0]:
                continue
            if self.allocate_modulo(items, t, fixed, ii)[1] > self.max_registers:
                continue  # a cheaper block the register file cannot hold
            best = (cost, t, ii, stages, depth)
        if best is not None:
            return best[1:]
        raise LoopError(f"{sname}: no modulo schedule found")

    @staticmethod
    def _modulo_place(items, ii, wd, height, budget, edges):
        """Iterative modulo scheduling (Rau): ``edges`` are (a, b, delay) with t_b >= t_a +
        delay (loop-carried ones already net of II). The highest unscheduled item goes to
        its earliest start (from its scheduled predecessors) or the first cycle after it
        with its issue slot, write slot and iterative unit free modulo II; when none is
        free it takes the earliest start anyway (or one past its last cycle) and evicts
        the items it conflicts with and the successors whose edges it breaks. Returns the
        offsets, or None when the budget of placements runs out."""
        n = len(items)
        unit = [UNIT_OF.get(it.kind) for it in items]
        occ = [[] for _ in range(n)]  # resources an item holds at cycle c (filled on place)

        def resources(k, c):
            res = [("issue", c % ii)]
            if wd[k] is not None:
                res.append(("write", (c + wd[k]) % ii))
            if unit[k] in INTERVAL:
                res.extend((unit[k], (c + i) % ii) for i in range(INTERVAL[unit[k]]))
            return res

        into = [[] for _ in range(n)]
        outof = [[] for _ in range(n)]
        for a, b, d in edges:
            into[b].append((a, d))
            outof[a].append((b, d))
        t = [None] * n
        last = [None] * n
        held: dict = {}  # resource -> item
        todo = set(range(n))

        def unplace(j):
            for r in occ[j]:
                held.pop(r, None)
            occ[j] = []
            t[j] = None
            todo.add(j)

        while todo:
            if budget <= 0:
                return None
            budget -= 1
            k = max(todo, key=lambda x: (height[x], -x))
            est = 0
            for a, d in into[k]:
                if t[a] is not None and a != k:
                    est = max(est, t[a] + d)
            if last[k] is not None and last[k] >= est:  # placed there before: move on
                est = last[k] + 1
            choice = None
            for c in range(est, est + ii):
                if all(r not in held for r in resources(k, c)):
                    choice = c
                    break
            if choice is None:
                choice = est
            for r in resources(k, choice):
                if r in held:  # evict
                    unplace(held[r])
            for b, d in outof[k]:
                if b != k and t[b] is not None and t[b] < choice + d:
                    unplace(b)
            t[k] = last[k] = choice
            occ[k] = resources(k, choice)
            for r in occ[k]:
                held[r] = k
            todo.discard(k)
        # compaction: each item (earliest first) moves to the earliest cycle its edges and
        # the free resources allow, until nothing moves (eviction leaves items late)
        moved = True
        while moved:
            moved = False
            for k in sorted(range(n), key=lambda x: t[x]):
                lo = max([t[a] + d for a, d in into[k] if a != k] + [0])
                for c in range(lo, t[k]):
                    if any(t[b] < c + d for b, d in outof[k] if b != k):
                        continue
                    if all(held.get(r, k) == k for r in resources(k, c)):
                        for r in occ[k]:
                            held.pop(r, None)
                        t[k] = c
                        occ[k] = resources(k, c)
                        for r in occ[k]:
                            held[r] = k
                        moved = True
                        break
        return t

    def allocate_modulo(self, items, issue, fixed, ii):
        """Temporaries of an overlapped block -> registers above the fixed ones. A
        temporary lands at ``w`` and is last read at ``r`` (``r - w <= II``); every
        iteration's copy lands II cycles after the one before, in the same register. Two
        temporaries share a register when neither lands (modulo II) strictly inside the
        other's life."""
        reg_of = dict(fixed)
        temps = sorted((w, w if r is None else max(w, r), name)
                       for w, r, name in _lives(items, issue, fixed))
        occupants: list = []  # per register above nfixed: (landing residues, life residues)
        for w, r, name in temps:
            land = w % ii
            life = {x % ii for x in range(w + 1, r)}
            for i, (lands, lives) in enumerate(occupants):
                if land not in lives and not (life & lands) and land not in lands:
                    lands.add(land)
                    lives.update(life)
                    reg_of[name] = self.nfixed + i
                    break
            else:
                occupants.append(({land}, set(life)))
                reg_of[name] = self.nfixed + len(occupants) - 1
        return reg_of, self.nfixed + len(occupants)

    # -- registers
    def allocate(self, items, issue, fixed):
        """Temporaries -> registers above the fixed ones: a value holds its register from
        its write to its last read (interval allocation in write order)."""
        reg_of = dict(fixed)
        temps = sorted((w, -1 if r is None else r, name)
                       for w, r, name in _lives(items, issue, fixed))
        free_at: list = []  # (cycle the register is free from, register)
        pool: list = []
        next_reg = self.nfixed
        top = next_reg
        for w, r, name in temps:
            while free_at and free_at[0][0] <= w:
                _, reg = heapq.heappop(free_at)
                heapq.heappush(pool, reg)
            if pool:
                reg = heapq.heappop(pool)
            else:
                reg = next_reg
                next_reg += 1
            reg_of[name] = reg
            # free once its last read is past: a later write lands after that read
            heapq.heappush(free_at, (max(r, w) + 1, reg))
            top = max(top, next_reg)
        return reg_of, top

    def block(self, sname: str, lowered) -> Block:
        """Schedule, allocate and encode a lowered nest (every nest is lowered first, so
        that the constants and accumulators own their registers before any temporary is
        placed above them). A nest named in ``overlap`` becomes a software pipeline unless
        the plain block is as fast, or the pipeline finds no schedule that could beat it,
        or needs more registers than the machine has."""
        items, fixed, n_it, step = lowered
        plain, top = self.plain_block(sname, items, fixed, n_it, step)
        if n_it > 1 and sname in self.overlap:
            try:  # the pipeline's registers fit (modulo_schedule keeps only such)
                piped, p_top = self.overlapped_block(sname, items, fixed, n_it, step,
                                                     plain.run_cycles)
            except LoopError:
                piped = None
            if piped is not None and piped.run_cycles < plain.run_cycles:
                plain, top = piped, p_top
        if top > self.max_registers:
            raise LoopError(f"{sname}: needs {top} registers; the machine has "
                            f"{self.max_registers}")
        self.top = max(getattr(self, "top", 0), top)
        return plain

    def plain_block(self, sname, items, fixed, n_it, step) -> tuple[Block, int]:
        """The block whose iterations do not overlap, and the registers it uses."""
        issue, length = self.schedule(sname, items)
        reg_of, top = self.allocate(items, issue, fixed)
        rows = self.rows(items, {issue[k]: k for k in range(len(items))}, length, reg_of)
        return Block(sname, n_it, rows, length, len(items), step), top

    def overlapped_block(self, sname, items, fixed, n_it, step,
                         bound: int) -> tuple[Block, int]:
        """A nest's block software-pipelined (:meth:`modulo_schedule`, the kernel under
        ``bound`` cycles a run), and the registers it uses: the kernel's II cycles of
        rows (a row's ``back`` its stage times ``step``), run ``n_it + stages - 1`` times,
        then a nop for the drain of the last iteration's writes."""
        issue, ii, stages, depth = self.modulo_schedule(sname, items, fixed, n_it, bound)
        reg_of, top = self.allocate_modulo(items, issue, fixed, ii)
        rows = self.rows(items, {issue[k] % ii: k for k in range(len(items))}, ii, reg_of,
                         back=lambda k: (issue[k] // ii) * step)
        kernel_rows = len(rows)
        tail = max(0, depth - stages * ii)
        if tail:
            rows.append(Row("nop", count=tail))
        return Block(sname, n_it + stages - 1, rows, ii, len(items), step,
                     kernel_rows=kernel_rows, tail=tail, valid_trips=n_it, stages=stages,
                     overlapped=True), top

    def rows(self, items, at: dict, length: int, reg_of: dict, back=None) -> list:
        """The rows of ``length`` cycles: the item ``at[c]`` in cycle c (its ``back`` from
        ``back(item index)``), each idle run one ``nop``."""
        rows: list = []
        c = 0
        while c < length:
            if c in at:
                row = self.row(items[at[c]], reg_of)
                if back is not None:
                    row.back = back(at[c])
                rows.append(row)
                c += 1
                continue
            k = c
            while k < length and k not in at and k - c < (1 << COUNT_BITS) - 1:
                k += 1
            rows.append(Row("nop", count=k - c))
            c = k
        return rows

    def row(self, it: _Item, reg_of: dict) -> Row:
        tb = self.put_table(it.table[0]) + it.table[1] if it.table is not None else 0
        if it.kind in UNIT_OF:
            a = reg_of[it.srcs[0]]
            b = reg_of[it.srcs[-1]]
            return Row(it.kind, dst=reg_of[it.dst], a=a, na=it.neg[0], b=b,
                       nb=it.neg[-1])
        if it.kind == "mov":
            dst = it.fixed_dst if it.fixed_dst is not None else reg_of[it.dst]
            return Row("mov", dst=dst, a=reg_of[it.srcs[0]], na=it.neg[0], mode=it.mode,
                       tb=tb)
        if it.kind == "load":
            return Row("load", dst=reg_of[it.dst], base=it.base, mode=it.mode, tb=tb)
        if it.kind == "store":
            return Row("store", a=reg_of[it.srcs[0]], base=it.base, mode=it.mode, tb=tb)
        raise LoopError(f"unknown item {it.kind}")


def compile_program(prog: SequenceProgram, reg_arrays=None,
                    max_registers: int = 1 << REG_BITS, init: dict | None = None,
                    unroll: dict | None = None, overlap=()) -> RegisterProgram:
    """Compile ``prog`` for the register machine. ``reg_arrays``: the arrays kept in the
    register file (default: those only straight-line segments touch, by constant
    addresses). ``init``: array -> {word: value}, the words the memories hold from
    configuration (constants of the program's arrays, e.g. a table's 1.0), which no run
    and no host write needs to rewrite. ``unroll``: segment -> copies (that many
    consecutive iterations in one, for the scheduler to interleave; a nest of sums
    interleaved over d tracks takes d copies). ``overlap``: the nests whose block
    iterations overlap (software pipelining, :meth:`_Compiler.modulo_schedule`), or True
    for every nest."""
    check_sequence(prog)
    if not 2 <= max_registers <= 1 << REG_BITS:
        raise LoopError(f"max_registers must be 2 .. {1 << REG_BITS} (the register fields "
                        f"are {REG_BITS} bits)")
    rom = init
    if reg_arrays is None:
        in_nests = {a for s in prog.segments.values() if s.trips for a in s.arrays}
        reg_arrays = [a for a in prog.arrays if a not in in_nests]
    used = dict.fromkeys(s for segs in prog.entries.values() for s in segs)
    if overlap is True:
        overlap = [s for s in used if prog.segments[s].trips]
    unknown = set(overlap) - set(prog.segments)
    if unknown:
        raise LoopError(f"{prog.name}: overlap names unknown segments {sorted(unknown)}")
    comp = _Compiler(prog, reg_arrays, max_registers, overlap)
    unroll = dict(unroll or {})
    unknown = set(unroll) - set(prog.segments)
    if unknown:
        raise LoopError(f"{prog.name}: unroll names unknown segments {sorted(unknown)}")
    lowered = {s: comp.lower(s, prog.segments[s], unroll.get(s, 1)) for s in used}
    blocks = {s: comp.block(s, low) for s, low in lowered.items()}
    init = [0] * max(comp.top, comp.nfixed)
    for name, reg in comp.constants.items():
        init[reg] = F.float_to_bits(const_value(name))
    for reg, name in comp.acc_init.items():
        init[reg] = F.float_to_bits(const_value(name))
    data_init = [0] * comp.data_words
    for array, words in (rom or {}).items():
        if array not in prog.arrays:
            raise LoopError(f"{prog.name}: initial words for unknown array {array!r}")
        for word, value in words.items():
            if not 0 <= int(word) < prog.arrays[array]:
                raise LoopError(f"{prog.name}: initial word {array}[{word}] out of range")
            if array in comp.reg_arrays:
                init[comp.reg_arrays[array] + int(word)] = _flush(F.float_to_bits(value))
            else:
                data_init[comp.data_arrays[array] + int(word)] = _flush(F.float_to_bits(value))
    restore = {reg: F.float_to_bits(const_value(name)) for reg, name in comp.acc_init.items()}
    return RegisterProgram(prog, blocks, dict(prog.entries), dict(comp.reg_arrays),
                           dict(comp.data_arrays), dict(comp.constants), len(init), init,
                           list(comp.table), comp.data_words, data_init, restore)


# ------------------------------------------------------------------ instruction-level model

#: the units as the bit-true float32 functions the cores are verified against
_BINARY = {"add": F.fp32_add, "sub": F.fp32_sub, "mul": F.fp32_mul, "div": F.fp32_div}


def _flush(w: int) -> int:
    return int(F.flush_subnormal(np.uint32(w)))


def _flip(w: int, f: int) -> int:
    """The operand path's sign flip (:func:`~navgate.numerics.fp32.fp32_neg`, as
    :func:`navgate.opflow.sequence._neg` builds it)."""
    return int(F.fp32_neg(np.uint32(w))) if f else w


def _unit(kind: str, a: int, b: int) -> int:
    x, y = np.uint32(a), np.uint32(b)
    if kind in ("lt", "le"):
        c = F.fp32_compare(x, y)
        return ONE_BITS if c["lt"] or (kind == "le" and c["eq"]) else 0
    if kind == "sqrt":
        return int(F.fp32_sqrt(x))
    return int(_BINARY[kind](x, y))


def run_register_program(rp: RegisterProgram, memories: dict, entry: str) -> tuple[dict, int]:
    """Run ``entry`` of the compiled program cycle by cycle as the machine does from its
    initial memories with ``memories`` (array -> words) written over them (rows,
    register writes at their cycles, table entries, skips): returns (array -> uint32 words,
    cycles from start to done). The check of the compiler against
    :func:`~navgate.opflow.sequence.run_sequence`, and of the machine against this."""
    prog = rp.program
    regs = list(rp.reg_init)
    data = list(rp.data_init) + [0] * max(0, 1 - rp.data_words)
    for a, v in memories.items():  # what the host writes; the rest keeps its initial words
        v = np.asarray(v)
        words = [int(x) for x in F.flush_subnormal(v if v.dtype == np.uint32 else
                                                    F.f32_to_bits(v))]
        if a in rp.reg_arrays:
            for i, x in enumerate(words):
                regs[rp.reg_arrays[a] + i] = x
        else:
            for i, x in enumerate(words):
                data[rp.data_arrays[a] + i] = x
    cycle = 2
    for bname in rp.entries[entry]:
        blk = rp.blocks[bname]
        last_valid = (blk.valid_trips - 1) * blk.step
        pending: dict = {}  # cycle -> [(register, word)]
        stores: dict = {}
        c = 0
        runs = [(k * blk.step, blk.rows[:blk.kernel_rows]) for k in range(blk.trips)]
        runs.append((0, blk.rows[blk.kernel_rows:]))
        for n_k, rows in runs:
            for row in rows:
                if row.kind == "nop":
                    for t in range(c, c + row.count):
                        _land(pending, stores, t, regs, data)
                    c += row.count
                    continue
                n = n_k - row.back  # the row's iteration (overlapped blocks)
                if 0 <= n <= last_valid:
                    _issue(rp, row, n, c, regs, data, pending, stores)
                # the row read the registers as they were before this cycle's writes
                _land(pending, stores, c, regs, data)
                c += 1
            if not blk.overlapped and (pending or stores):  # an iteration drains its writes
                raise LoopError(f"{bname}: a write at {min(set(pending) | set(stores))} "
                                f"after its iteration's {c} cycles")
        late = set(pending) | set(stores)  # every cycle up to c - 1 has landed
        if late:
            raise LoopError(f"{bname}: a write at {min(late)} after the block's {c} cycles")
        cycle += c
    out = {}
    for a, w in prog.arrays.items():
        if a in rp.reg_arrays:
            out[a] = np.array(regs[rp.reg_arrays[a]:rp.reg_arrays[a] + w], np.uint32)
        else:
            out[a] = np.array(data[rp.data_arrays[a]:rp.data_arrays[a] + w], np.uint32)
    return out, cycle


def _issue(rp, row, n, c, regs, data, pending, stores):
    """Issue ``row`` for iteration ``n`` in cycle ``c``: its writes join ``pending`` and
    ``stores`` at the cycles they land."""
    entry_v = rp.table[row.tb + n] if row.mode == M_TABLE else 0
    if row.kind in UNIT_OF:
        w = _unit(row.kind, _flip(regs[row.a], row.na), _flip(regs[row.b], row.nb))
        pending.setdefault(c + write_delay(row.kind), []).append((row.dst, w))
    elif row.kind == "mov":
        if entry_v != SKIP:
            pending.setdefault(c + write_delay("mov"), []).append(
                (row.dst, _flip(regs[row.a], row.na)))
    elif row.kind == "load":
        pending.setdefault(c + write_delay("load"), []).append(
            (row.dst, data[_address(row, n, entry_v)]))
    elif row.kind == "store":
        if entry_v != SKIP:
            stores.setdefault(c + STORE_WRITE, []).append((_address(row, n, entry_v),
                                                          regs[row.a]))


def _address(row: Row, n: int, entry_v: int) -> int:
    if row.mode == M_CONST:
        return row.base
    if row.mode == M_LINEAR:
        return row.base + n
    return row.base + entry_v


def _land(pending, stores, t, regs, data):
    if len(pending.get(t, ())) > 1:
        raise LoopError(f"two register writes in cycle {t}: the machine has one write port")
    for reg, w in pending.pop(t, []):
        regs[reg] = w
    for addr, w in stores.pop(t, []):
        data[addr] = w


# ------------------------------------------------------------------ the machine


class RegisterMachine(wiring.Component):
    """The register machine of a :class:`RegisterProgram` (module docstring).

    Handshake: ``start`` (one cycle, while ``busy`` is low; ``entry``: the entry's number,
    :meth:`entry_index`) runs the entry; ``done`` is high for one cycle
    :meth:`RegisterProgram.cycles` cycles after the start cycle. Host port, while idle:
    ``host_addr`` = 1 << 10 | register, or a data-memory word (:meth:`host_address`);
    ``host_rdata`` holds the word of the address presented in the cycle before; written words
    are flushed (a subnormal becomes the zero of its sign)."""

    def __init__(self, rp: RegisterProgram):
        self.rp = rp
        self.words, self.where, self.steps, self.first, self.backs = rp.layout()
        self.entry_names = list(rp.entries)
        super().__init__({"start": In(1), "entry": In(_bits(len(rp.entries))),
                          "busy": Out(1), "done": Out(1),
                          "host_addr": In(BASE_BITS + 1), "host_wdata": In(32),
                          "host_we": In(1), "host_rdata": Out(32)})

    def host_address(self, array: str, word: int) -> int:
        return self.rp.host_address(array, word)

    def entry_index(self, entry: str) -> int:
        return self.entry_names.index(entry)

    @property
    def instruction_rows(self) -> int:
        return len(self.words)

    def elaborate(self, platform):  # noqa: C901 - one datapath, read top to bottom
        rp = self.rp
        m = Module()
        nreg = max(rp.registers, 2)
        irom = Memory(shape=INSTR_BITS, depth=max(len(self.words), 2),
                      init=self.words)
        trom = Memory(shape=TABLE_BITS, depth=max(len(rp.table), 2),
                      init=rp.table)
        # the register file in LUT RAM (two read ports, one write port), so that block RAM
        # holds the instruction ROM, the table ROM and the data memory only
        regs = Memory(shape=32, depth=nreg, init=rp.reg_init,
                      attrs={"ram_style": "distributed"})
        data = Memory(shape=32, depth=max(rp.data_words, 2), init=rp.data_init)
        m.submodules.irom, m.submodules.trom = irom, trom
        m.submodules.regs, m.submodules.data = regs, data
        ir_port = irom.read_port()
        tr_port = trom.read_port()
        ra = regs.read_port(transparent_for=())
        rb = regs.read_port(transparent_for=())
        rw = regs.write_port()
        dr = data.read_port(transparent_for=())
        dw = data.write_port()

        # after every reset (and at configuration) the accumulators that are re-armed at the
        # end of their nests get their init words again, one per cycle: a run cut short by
        # a reset would otherwise leave a partial sum in one (LUT RAM keeps its words)
        restore_words = sorted(rp.acc_restore.items())
        restoring = Signal()
        if restore_words:
            restore = Signal(range(len(restore_words) + 1))
            m.d.comb += restoring.eq(restore != len(restore_words))
            r_addr = Array([Const(r, REG_BITS) for r, _ in restore_words])[restore]
            r_word = Array([Const(w, 32) for _, w in restore_words])[restore]

        # ---- sequencer: a fetch stage (the row at the ROM's output, ``f_*``) and an issue
        # stage (the row in the instruction register ``ir``, ``i_*``). Branches are decided
        # at fetch from registers; a ``nop k`` in the instruction register holds both
        # stages for k cycles (the ROM's read enable low), decided from the register. So
        # no path runs from the ROM's output back to its address.
        steps = self.steps
        sw = _bits(len(steps))
        pcw = _bits(len(self.words))
        nw = max(1, max(s[2] for s in steps).bit_length())
        st_first = Array([Const(s[0], pcw) for s in steps])
        st_last = Array([Const(s[1], pcw) for s in steps])
        st_trips = Array([Const(s[2], nw) for s in steps])
        st_end = Array([Const(s[3], 1) for s in steps])
        sinc = max(1, max(s[4] for s in steps).bit_length())
        st_inc = Array([Const(s[4], sinc) for s in steps])
        st_tail = Array([Const(s[5], pcw) for s in steps])
        st_valid = Array([Const(s[6], nw) for s in steps])
        en_first = Array([Const(self.first[e], sw) for e in self.entry_names])
        f_valid, f_last = Signal(), Signal()
        f_step = Signal(sw)
        f_pc = Signal(pcw)
        f_n = Signal(nw)
        i_valid, i_last = Signal(), Signal()
        ir = Signal(INSTR_BITS)
        n = Signal(nw)  # the issued row's iteration (n of the kernel iteration - back)
        i_pred = Signal()  # that iteration exists (an overlapped block's prologue/epilogue)
        wc = Signal(COUNT_BITS)
        kind = ir[0:4]
        is_nop = kind == KIND_CODE["nop"]
        count = ir[12:28]
        hold = Signal()
        m.d.comb += hold.eq(i_valid & is_nop & (wc + 1 < count))
        m.d.comb += self.busy.eq(f_valid | i_valid | restoring)
        m.d.sync += self.done.eq(0)
        # the row's back (stage x step) from the fetched address: a ROM in logic beside the
        # instruction ROM (zero outside overlapped blocks), and the row's iteration and
        # predicate from it, registered with the row
        bw = max(1, max(self.backs, default=0).bit_length())
        if any(self.backs):
            back_rom = Array([Const(b, bw) for b in self.backs])
            f_back = Signal(bw)
            m.d.comb += f_back.eq(back_rom[f_pc])
            f_row_n = Signal(nw + 1)
            m.d.comb += f_row_n.eq(f_n - f_back)
            f_pred = (f_n >= f_back) & (f_row_n[:nw] <= st_valid[f_step])
        else:
            f_row_n, f_pred = f_n, Const(1, 1)
        # the next row to fetch after f_pc (from registers only): a block's kernel
        # (first .. last) repeats, then the rows after it (to tail) run once
        last_iter = f_n == st_trips[f_step]
        at_last = f_pc == st_last[f_step]
        at_tail = f_pc == st_tail[f_step]
        nx_pc, nx_n, nx_step = Signal(pcw), Signal(nw), Signal(sw)
        nx_valid, nx_last = Signal(), Signal()
        with m.If(last_iter & at_tail):
            m.d.comb += [nx_pc.eq(st_first[f_step + 1]), nx_n.eq(0),
                         nx_step.eq(f_step + 1), nx_valid.eq(~st_end[f_step])]
        with m.Elif(~last_iter & at_last):
            m.d.comb += [nx_pc.eq(st_first[f_step]), nx_n.eq(f_n + st_inc[f_step]),
                         nx_step.eq(f_step), nx_valid.eq(1)]
        with m.Else():
            m.d.comb += [nx_pc.eq(f_pc + 1), nx_n.eq(f_n), nx_step.eq(f_step),
                         nx_valid.eq(1)]
        # the row after nx is the entry's end: nx is the entry's final row
        m.d.comb += nx_last.eq((nx_pc == st_tail[nx_step]) & (nx_n == st_trips[nx_step])
                               & st_end[nx_step])
        with m.If(hold):
            m.d.sync += wc.eq(wc + 1)
            m.d.comb += ir_port.en.eq(0)
        with m.Else():
            m.d.sync += [wc.eq(0), ir.eq(ir_port.data), n.eq(f_row_n), i_pred.eq(f_pred),
                         i_valid.eq(f_valid), i_last.eq(f_valid & f_last)]
            m.d.comb += ir_port.en.eq(1)
            with m.If(i_valid & i_last):
                m.d.sync += self.done.eq(1)
            with m.If(f_valid):
                m.d.comb += ir_port.addr.eq(nx_pc)
                m.d.sync += [f_pc.eq(nx_pc), f_n.eq(nx_n), f_step.eq(nx_step),
                             f_valid.eq(nx_valid & ~f_last), f_last.eq(nx_last)]
            with m.Elif(self.start & ~i_valid & ~restoring):
                first = en_first[self.entry]
                m.d.comb += ir_port.addr.eq(st_first[first])
                m.d.sync += [f_pc.eq(st_first[first]), f_n.eq(0), f_step.eq(first),
                             f_valid.eq(1),
                             f_last.eq((st_first[first] == st_tail[first])
                                       & (st_trips[first] == 0) & st_end[first])]
        active = Signal()
        m.d.comb += active.eq(i_valid)

        # ---- issue (cycle c): register and table reads
        issue = Signal()
        m.d.comb += issue.eq(i_valid & ~is_nop & i_pred)
        is_store = kind == KIND_CODE["store"]
        f_dst, f_a, f_na, f_b, f_nb = ir[4:12], ir[12:20], ir[20], ir[21:29], ir[29]
        f_base, f_mode, f_tb = ir[12:22], ir[22:24], ir[24:36]
        host_reg = self.host_addr[BASE_BITS]
        with m.If(active):
            m.d.comb += [ra.addr.eq(Mux(is_store, f_dst, f_a)), rb.addr.eq(f_b)]
        with m.Else():
            m.d.comb += ra.addr.eq(self.host_addr[:REG_BITS])
        m.d.comb += tr_port.addr.eq(f_tb + n)
        # stage 1 (c + 1)
        s1_valid = Signal()
        s1_kind = Signal(4)
        s1_dst = Signal(REG_BITS)
        s1_na, s1_nb = Signal(), Signal()
        s1_mode = Signal(2)
        s1_base = Signal(BASE_BITS)
        s1_n = Signal(nw)
        m.d.sync += [s1_valid.eq(issue), s1_kind.eq(kind), s1_dst.eq(f_dst), s1_na.eq(f_na),
                     s1_nb.eq(f_nb), s1_mode.eq(f_mode), s1_base.eq(f_base), s1_n.eq(n)]
        op_a = Mux(s1_na, _neg(m, ra.data), ra.data)
        op_b = Mux(s1_nb, _neg(m, rb.data), rb.data)
        entry_v = tr_port.data
        skip = (s1_mode == M_TABLE) & (entry_v == SKIP)
        daddr = Signal(BASE_BITS)
        m.d.sync += daddr.eq(s1_base + Mux(s1_mode == M_LINEAR, s1_n,
                                           Mux(s1_mode == M_TABLE, entry_v, 0)))
        k1 = {k: s1_valid & (s1_kind == KIND_CODE[k]) for k in KIND_CODE}
        # stage 2 (c + 2): the operands registered for the units, the store's word and
        # enable and the data address registered for the data memory
        s2_valid, s2_kind, s2_dst = Signal(), Signal(4), Signal(REG_BITS)
        s2_a, s2_b = Signal(32), Signal(32)
        s2_store, s2_load = Signal(), Signal()
        s2_word = Signal(32)  # a store's word: bit 20 of its row is an address bit, not na
        m.d.sync += [s2_valid.eq(s1_valid), s2_kind.eq(s1_kind), s2_dst.eq(s1_dst),
                     s2_a.eq(op_a), s2_b.eq(op_b), s2_word.eq(ra.data),
                     s2_store.eq(k1["store"] & ~skip),
                     s2_load.eq(k1["load"])]
        k2 = {k: s2_valid & (s2_kind == KIND_CODE[k]) for k in KIND_CODE}

        # ---- units
        used = {UNIT_OF[r.kind] for b in rp.blocks.values() for r in b.rows
                if r.kind in UNIT_OF}
        writes = []  # (enable, register, word)
        for u in ("mul", "add", "div", "sqrt", "cmp"):
            if u not in used:
                continue
            core = UNIT_CLASS[u]()
            m.submodules[u] = core
            kinds = [k for k, uu in UNIT_OF.items() if uu == u]
            go = Signal(name=f"{u}_go")
            m.d.comb += go.eq(Cat(*[k2[k] for k in kinds]).any())
            m.d.comb += [core.i.valid.eq(go), core.o.ready.eq(1), core.i.payload.a.eq(s2_a)]
            if u != "sqrt":
                m.d.comb += core.i.payload.b.eq(s2_b)
            if u == "add":
                m.d.comb += core.i.payload.sub.eq(s2_kind == KIND_CODE["sub"])
            # the destination (and a comparison's kind) ride a delay line of the latency
            v_line, d_line, le_line = go, s2_dst, s2_kind == KIND_CODE["le"]
            for t in range(LATENCY[u]):
                v2, d2, l2 = Signal(name=f"{u}_v{t}"), Signal(REG_BITS, name=f"{u}_d{t}"), \
                    Signal(name=f"{u}_le{t}")
                m.d.sync += [v2.eq(v_line), d2.eq(d_line), l2.eq(le_line)]
                v_line, d_line, le_line = v2, d2, l2
            if u == "cmp":
                p = core.o.payload
                word = Mux(p.lt | (le_line & p.equal), ONE_BITS, 0)
            else:
                word = core.o.payload.r
            writes.append((v_line, d_line, word))
        # mov: c + 2
        s2_mov = Signal()
        m.d.sync += s2_mov.eq(k1["mov"] & ~skip)
        writes.append((s2_mov, s2_dst, s2_a))
        # load: data read in c + 2, register write in c + 3
        s3_load = Signal()
        s3_dst = Signal(REG_BITS)
        m.d.sync += [s3_load.eq(s2_load), s3_dst.eq(s2_dst)]
        writes.append((s3_load, s3_dst, dr.data))

        # ---- host port (idle) and the write ports
        hw = self.host_wdata
        host_word = Signal(32)
        m.d.comb += host_word.eq(Mux(hw[23:31] == 0, Cat(Const(0, 31), hw[31]), hw))
        # every write of a block lands within it (the compiler's rule), so the host port
        # has the write ports whenever the machine is idle
        with m.If(active):
            for en, reg, word in writes:
                with m.If(en):
                    m.d.comb += [rw.en.eq(1), rw.addr.eq(reg), rw.data.eq(word)]
        with m.Elif(self.host_we & host_reg):
            m.d.comb += [rw.en.eq(1), rw.addr.eq(self.host_addr[:REG_BITS]),
                         rw.data.eq(host_word)]
        if restore_words:
            with m.Elif(restoring):  # a host write waits no cycle: the restore does
                m.d.comb += [rw.en.eq(1), rw.addr.eq(r_addr), rw.data.eq(r_word)]
                m.d.sync += restore.eq(restore + 1)
        with m.If(active):
            m.d.comb += [dr.addr.eq(daddr), dw.addr.eq(daddr), dw.data.eq(s2_word),
                         dw.en.eq(s2_store)]
        with m.Else():
            m.d.comb += [dr.addr.eq(self.host_addr[:BASE_BITS]),
                         dw.addr.eq(self.host_addr[:BASE_BITS]), dw.data.eq(host_word),
                         dw.en.eq(self.host_we & ~host_reg)]
        host_sel = Signal()
        m.d.sync += host_sel.eq(host_reg)
        m.d.comb += self.host_rdata.eq(Mux(host_sel, ra.data, dr.data))
        return m


def simulate_register_machine(rp: RegisterProgram, memories: dict, entries: list):
    """Run the register machine in Amaranth's simulator
    (:func:`navgate.opflow.loopmachine.simulate_entries`): write ``memories`` through the host
    port, run ``entries`` (names, or (name, memories to write first)); one (array -> uint32
    words, cycles from start to done) per entry run."""
    return simulate_entries(RegisterMachine(rp), rp.program.arrays, memories, entries,
                            lambda e: 2 * rp.cycles(e) + 100)
