"""The op-program list scheduler of navgate's scheduled float32 datapaths: the op form
(SSA ops, commit map, outputs), the unit kinds and latencies, the banked list scheduler with
its port and bank rules, bank assignment and register allocation. It knows no client system:
programs come from their clients (``systems/``); :mod:`navgate.opflow.machine` turns a
schedule into the banked datapath and its control.

Op form
-------
The op form shared by navgate's scheduled float32 datapaths.

Programs
--------
A program is a list of ops with ``dst``, ``kind`` and ``srcs`` (SSA: every ``dst`` is a new
temporary), a ``commit`` map (register <- temporary, all reads of a register in the program
see its value at program start) and ``outputs`` (name -> temporary) -- the form the clients'
program builders produce. Kinds: ``add sub mul div sqrt le lt
cvt neg``; ``neg`` is a sign flip folded into its consumers' operand paths
(:func:`_fold_negs`; it must feed arithmetic ops only). Register names that are not
temporaries are persistent: ``c:<hex>`` constants (initial contents) and the names the
machine's image lists. Cores: ``mul`` (Fp32Mul, 5), ``add`` (Fp32Add, add/sub, 8), ``div``,
``sqrt``, ``cmp`` (Fp32Compare, 2, result 1.0/0.0), ``cvt`` (Fp32FromInt(32): a register
holding a two's complement integer, 4) and ``mov`` (a one-cycle copy for commits that cannot
be written in place).


Banked scheduling
-----------------
The list scheduler for a register file split into single-write-port banks that map onto block
RAM; :mod:`navgate.opflow.machine` is the Amaranth machine that executes the schedule.

Reference: resource-constrained list scheduling with register-bank (port) constraints, as in
clustered VLIW compilers and high-level synthesis with multi-bank memories (Gajski et al.,
"High-Level Synthesis", 1992, ch. 7 and 8; Lapinskii, Jacome and de Veciana, "Cluster
assignment for high-performance embedded VLIW processors", ACM TODAES 7(3), 2002). An
earlier machine gave every unit its own read and write ports on one register file; on a
7-series part that became flip-flops and wide multiplexers (151,653 LUT for the 26-state INS
mechanization) and it was removed. Here every bank has **one
write port** and ``read_ports`` read ports (synchronous, not transparent), which is what a
block RAM (one simple-dual-port RAMB18 per read port) or LUT RAM provides, and the scheduler
keeps every cycle within those ports. Measured on its clients in docs/ (architecture.md
lists which document).

Machine
-------
* Issue slots: ``mul`` instances, ``add`` instances (add/sub) and one ``misc`` slot shared by
  div, sqrt, compare, int->float conversion and the commit copy ``mov``; each slot issues at
  most one op per cycle and has two operand ports.
* Banks: one per issue slot (``mul0..``, ``add0..``, and ``misc`` unless ``misc_bank`` is
  off). Each bank: one write port whose data comes from any mul/add unit's result or the
  misc cores' shared result bus (at most one misc result per cycle, a scheduling
  constraint; a multiplexer set by the microcode), ``read_ports``
  read ports; every operand port selects one bank read port (a ``banks x read_ports``
  multiplexer set by the microcode). Persistent registers (state, configuration, inputs,
  constants) are spread over the banks; every temporary is placed by the scheduler in a bank
  whose write port is free in its write cycle (its own slot's bank first).
* Timing of an op issued in cycle ``c``: the control word of cycle ``c`` presents the operand
  addresses to the banks' read ports; in ``c + 1`` the read data pass the operand
  multiplexer (and the sign flip where a ``neg`` was folded) into the operand register; in
  ``c + 2`` they enter the unit; the result is valid in ``w = c + 2 + L`` and the control
  word of cycle ``w`` writes it at the end of ``w``. Reads are not transparent: an op issued
  in ``r`` sees the write iff ``w < r`` (ready ``L + 3`` cycles after issue), and a register
  may be overwritten in the cycle of its last read (the read returns the old word). The
  operand register keeps the block RAM's clock-to-out delay and the multiplexer out of the
  units' first stage (xc7 timing).
* Constraints per cycle: one issue per slot; per bank, at most ``read_ports`` distinct words
  read and one word written.
* True-dual-port banks (``BankedUnits(shared_write_port=True)``, two ports): port A is the
  write port and read port 0 on one address (the microcode's read-0 address field is the
  write address in a cycle that writes the bank), port B is read port 1, so Yosys maps a
  bank onto one true-dual-port block RAM. Per bank per cycle then: distinct words read +
  words written <= 2, and a bank written in a cycle is read through port B only. An op
  that cannot read its operands because their bank is written reserves the next cycle in
  which that bank is not written yet (no later write may take it), so that a stream of
  writes cannot starve it. On xc7 a 32-bit true-dual-port bank is one RAMB36E1 (a RAMB18E1
  has 18-bit ports in that mode), the same block RAM as two simple-dual-port RAMB18E1: the
  saving is the narrower microcode (measured in benchmarks/bench_tdp_banks.py).
* Split read ports (``BankedUnits(split_ports=True)``, two ports): operand port ``j`` of
  every slot reads read port ``j`` of some bank, so an operand multiplexer has one input per
  bank (8 rather than 16 with 4 + 4 slots: on xc7 3 LUTs a bit rather than 5) and its
  select field is a bank number. Per bank per cycle then: one word on each read port (an
  op may share a port with another op that reads the same word there). A commutative op
  whose sources do not fit in their order may take them swapped: ``x * y = y * x`` and
  ``x + y = y + x`` exactly (the result is the exact sum or product correctly rounded, and
  every NaN result is the canonical one), and ``x - y`` becomes ``(-y) + x`` (the flip bit
  of the operand); of two orders that fit, the one sharing more ports already read that
  cycle. Div, compare, convert and mov read their first source on port 0, as given.

Programs and commit rules are those above (SSA ops, commit
map read at program start, outputs): a committed temporary placed in its register's bank and
written no earlier than that register's last read is written in place, otherwise a ``mov``
copies it.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass, field

from navgate.gateware.fp32 import (
    Fp32Add,
    Fp32Compare,
    Fp32Div,
    Fp32DivIter,
    Fp32Mul,
    Fp32Sqrt,
    Fp32SqrtIter,
)

UNIT_OF_KIND = {"add": "add", "sub": "add", "mul": "mul", "div": "div", "sqrt": "sqrt",
                "le": "cmp", "lt": "cmp", "cvt": "cvt", "mov": "mov"}
UNIT_LATENCY = {"add": Fp32Add.LATENCY, "mul": Fp32Mul.LATENCY, "div": Fp32Div.LATENCY,
                "sqrt": Fp32Sqrt.LATENCY, "cmp": Fp32Compare.LATENCY, "cvt": 4, "mov": 1}
N_SRCS = {"mul": 2, "add": 2, "div": 2, "sqrt": 1, "cmp": 2, "cvt": 1, "mov": 1}
ONE_BITS = 0x3F800000
QNAN_BITS = 0x7FC00000


class ScheduleError(RuntimeError):
    """The program cannot be scheduled (unknown operand, unsupported neg use)."""


@dataclass
class SOp:
    """One scheduled operation: ``dst = kind(srcs)`` on instance ``inst`` of ``unit``."""

    index: int
    dst: str
    kind: str
    srcs: tuple  #: ((name, flip), ...)
    unit: str = ""
    inst: int = 0
    issue: int = -1
    height: int = 0



@dataclass
class ScheduledProgram:
    name: str
    ops: list  #: SOp, in issue order
    cycles: int  #: cycles from the first issue to the last write, inclusive
    commit: dict  #: register -> temporary
    outputs: dict  #: name -> temporary
    direct: dict = field(default_factory=dict)  #: temporary -> register it is written into
    last_use: dict = field(default_factory=dict)  #: temporary -> last read cycle

    def unit_busy(self) -> dict:
        out: dict = {}
        for s in self.ops:
            out[s.unit] = out.get(s.unit, 0) + 1
        return out


def _fold_negs(prog):
    """Ops without ``neg``: every operand becomes (name, flip)."""
    alias: dict = {}
    out = []
    for op in prog.ops:
        srcs = []
        for s in op.srcs:
            base, flip = alias.get(s, (s, False))
            srcs.append((base, flip))
        if op.kind == "neg":
            alias[op.dst] = (srcs[0][0], not srcs[0][1])
            continue
        out.append(SOp(len(out), op.dst, op.kind, tuple(srcs)))
    used = set(prog.commit.values()) | set(prog.outputs.values())
    for s in out:
        if s.kind == "cvt" and s.srcs[0][1]:
            used.add(s.dst)
    bad = [d for d in alias if d in used]
    if bad:
        raise ScheduleError(f"{prog.name}: neg result {bad[0]} is committed, output or "
                            "converted (only arithmetic consumers are folded)")
    return out


#: the cores sharing the misc issue slot, in select order
MISC_KINDS = ("div", "sqrt", "cmp", "cvt", "mov")
#: issue -> unit input: bank read (1) + operand multiplexer into the operand register (1)
OPERAND_STAGES = 2
#: issue -> readable: operand stages + latency + write-before-read (not transparent, 1)
OVERHEAD = OPERAND_STAGES + 1
#: the iterative cores used with ``BankedUnits(iterative=True)``
ITERATIVE = {"div": Fp32DivIter, "sqrt": Fp32SqrtIter}
#: a temporary read by at least this many ops goes to the least-read bank
SPREAD_FANOUT = 2
#: how far ahead a waiting op may reserve a write-free cycle (shared port A)
RESERVE_WINDOW = 64


@dataclass(frozen=True)
class BankedUnits:
    """Issue slots (and banks): ``mul`` and ``add`` instances, plus one misc slot."""

    mul: int = 3
    add: int = 3
    read_ports: int = 2
    #: the misc slot has a bank of its own; otherwise its results go to the other banks
    #: (fewer operand multiplexer inputs: 16 instead of 18 with 4 + 4 slots)
    misc_bank: bool = True
    #: the divider and square root are the iterative cores (Fp32DivIter, Fp32SqrtIter: one
    #: recurrence step reused, ~140 LUT each, a new op every INTERVAL cycles) instead of the
    #: pipelined ones (1,290 and 738 LUT, one op per cycle)
    iterative: bool = False
    #: true-dual-port banks: port A is the write port and read port 0 (one address, shared),
    #: port B is read port 1. Per bank per cycle: distinct words read + words written <= 2,
    #: and read port 0 is unavailable in a cycle the bank is written (its address is the
    #: write address). One address field per bank fewer in the microcode. Needs
    #: ``read_ports == 2``. ``True``: every bank; a tuple of bank numbers: those banks.
    shared_write_port: bool | tuple = False
    #: operand port ``j`` of every slot reads read port ``j`` of a bank (``read_ports == 2``):
    #: each operand multiplexer has one input per bank (8 instead of 16 with 4 + 4 slots).
    #: Per bank per cycle: one word on each read port; the scheduler swaps the operands of
    #: a commutative op (mul, add; a sub becomes an add of the negated subtrahend) to fit.
    split_ports: bool = False

    def shared(self, bank: int) -> bool:
        """Bank ``bank`` has a shared port A (write port = read port 0)."""
        sw = self.shared_write_port
        return bool(sw) if isinstance(sw, bool) else bank in sw

    def latency(self, unit: str) -> int:
        if self.iterative and unit in ITERATIVE:
            return ITERATIVE[unit].LATENCY
        return UNIT_LATENCY[unit]

    def interval(self, unit: str) -> int:
        if self.iterative and unit in ITERATIVE:
            return ITERATIVE[unit].INTERVAL
        return 1

    def slots(self) -> list:
        return ([("mul", k) for k in range(self.mul)] + [("add", k) for k in range(self.add)]
                + [("misc", 0)])

    def slot_of(self, unit: str, inst: int) -> int:
        if unit == "mul":
            return inst
        if unit == "add":
            return self.mul + inst
        return self.mul + self.add

    @property
    def banks(self) -> int:
        return self.mul + self.add + int(self.misc_bank)


def _slot_unit(unit: str) -> str:
    return unit if unit in ("mul", "add") else "misc"


class BSOp(SOp):
    """A scheduled op of the banked machine (result written ``OPERAND_STAGES + L`` cycles
    after issue, in bank ``bank``)."""

    bank = None
    lat = None  #: the unit's latency (set by the scheduler)

    @property
    def write(self) -> int:
        return self.issue + OPERAND_STAGES + self.lat

    @property
    def ready(self) -> int:
        return self.write + 1


def _ready(s: SOp) -> int:
    return s.issue + s.lat + OVERHEAD


#: kinds whose sources the split-port scheduler may swap (a sub as an add, :func:`_swap_sources`)
COMMUTATIVE = ("mul", "add", "sub")


def _swap_sources(s) -> None:
    """Swap the two sources of a commutative op in place: x*y = y*x and x+y = y+x exactly
    (correct rounding of the exact result, canonical NaN); x - y becomes (-y) + x."""
    (x, fx), (y, fy) = s.srcs
    if s.kind == "sub":
        s.kind = "add"
        fy = not fy
    s.srcs = ((y, fy), (x, fx))


def schedule_banked(prog, units: BankedUnits, bank_of: dict) -> ScheduledProgram:
    """List-schedule ``prog`` with bank constraints. ``bank_of``: persistent register ->
    bank. Every op gets ``issue``, ``inst`` (slot instance) and ``bank`` (of its result,
    attribute added here); movs are appended for commits that cannot be made in place."""
    if units.read_ports < 2:
        raise ScheduleError("read_ports must be at least 2 (an op may read two words of one "
                            "bank in one cycle)")
    shared = units.shared
    if any(shared(b) for b in range(units.banks)) and units.read_ports != 2:
        raise ScheduleError("shared_write_port (true-dual-port banks) needs read_ports == 2")
    split = units.split_ports
    if split and (units.read_ports != 2 or any(shared(b) for b in range(units.banks))):
        raise ScheduleError("split_ports needs read_ports == 2 and no shared write port")
    ops = [BSOp(s.index, s.dst, s.kind, s.srcs) for s in _fold_negs(prog)]
    producer = {s.dst: s for s in ops}
    for s in ops:
        s.unit = UNIT_OF_KIND[s.kind]
        for name, _ in s.srcs:
            if name not in producer and name not in bank_of:
                raise ScheduleError(f"{prog.name}: unknown operand {name} of {s.dst}")
    users: dict = {s.dst: [] for s in ops}
    for s in ops:
        for name, _ in s.srcs:
            if name in users and s not in users[name]:
                users[name].append(s)
    needed = set(prog.commit.values()) | set(prog.outputs.values())
    for s in reversed(ops):
        s.lat = units.latency(s.unit)
        lat = s.lat + OVERHEAD
        s.height = lat + max((u.height for u in users[s.dst]), default=0)
    commit_to = {}
    for reg, tmp in prog.commit.items():
        commit_to.setdefault(tmp, reg)
    npred = {s.index: len({n for n, _ in s.srcs if n in producer}) for s in ops}
    bank = {}  # value name -> bank (temporaries, as placed)
    reads: dict = {}  # (cycle, bank) -> set of names
    port_reads: dict = {}  # split ports: (cycle, bank, port) -> name
    writes: set = set()  # (cycle, bank)
    issued: set = set()  # (cycle, slot)
    pending = []
    for s in ops:
        if npred[s.index] == 0:
            heapq.heappush(pending, (0, -s.height, s.index))
    ready = {"mul": [], "add": [], "misc": []}
    nslots = {"mul": units.mul, "add": units.add, "misc": 1}
    nb = units.banks
    load = [0] * nb  # reads of the temporaries placed in each bank
    core_free: dict = {}  # iterative core -> first cycle it accepts a new op
    nowrite: set = set()  # (cycle, bank) kept free of writes for a waiting op's reads
    reserved: dict = {}  # op index -> the cycle reserved for it

    def bank_of_name(name):
        return bank[name] if name in bank else bank_of[name]

    def reads_fit(c, names):
        need: dict = {}
        for n in set(names):
            b = bank_of_name(n)
            need.setdefault(b, set()).add(n)
        for b, ns in need.items():
            have = reads.get((c, b), set())
            if len(have | ns) > read_limit(c, b):
                return False
        return True

    def read_limit(c, b):
        # a shared port A that writes in cycle c reads nothing
        return units.read_ports - int(shared(b) and (c, b) in writes)

    def write_free(w, b):
        # the write port is free, and with a shared port A, port B alone serves the reads
        return ((w, b) not in writes and (w, b) not in nowrite
                and not (shared(b) and len(reads.get((w, b), ())) > 1))

    def reserve(c, names):
        # shared port A: an op that cannot read its operands because their bank is written
        # in cycle c reserves the next cycle in which none of those banks is written yet
        # (no write may be placed there), so that a stream of writes cannot starve it
        need: dict = {}
        for n in set(names):
            need.setdefault(bank_of_name(n), set()).add(n)
        full = [b for b, ns in need.items()
                if len(reads.get((c, b), set()) | ns) > read_limit(c, b)
                and len(reads.get((c, b), set()) | ns) <= units.read_ports]
        if not full:
            return None
        for c2 in range(c + 1, c + RESERVE_WINDOW):
            if all((c2, b) not in writes for b in full):
                for b in full:
                    nowrite.add((c2, b))
                return c2
        return None

    def take_reads(c, names):
        for n in names:
            reads.setdefault((c, bank_of_name(n)), set()).add(n)

    def ports_fit(c, order):
        # split ports: source j on read port j of its bank, free or carrying the same word
        return all(port_reads.get((c, bank_of_name(n), j), n) == n
                   for j, n in enumerate(order))

    def orient(c, s):
        # split ports: whether the op takes its sources swapped to fit (a commutative op
        # may); None: no order fits
        names = [n for n, _ in s.srcs]
        orders = [names]
        if s.kind in COMMUTATIVE and len(names) == 2 and names[0] != names[1]:
            orders.append(names[::-1])
        fit = [order for order in orders if ports_fit(c, order)]
        if not fit:
            return None
        # the order that shares the most ports already read this cycle (the given order
        # on a tie): it leaves the most ports free for the ops still to be placed
        fit.sort(key=lambda o: -sum(port_reads.get((c, bank_of_name(n), j)) == n
                                    for j, n in enumerate(o)))
        return fit[0] != names

    def take_ports(c, names):
        for j, n in enumerate(names):
            port_reads[(c, bank_of_name(n), j)] = n

    placed = 0
    c = 0
    while placed < len(ops):
        while pending and pending[0][0] <= c:
            _, h, i = heapq.heappop(pending)
            heapq.heappush(ready[_slot_unit(ops[i].unit)], (h, i))
        for su in ("mul", "add", "misc"):
            q = ready[su]
            skipped = []
            inst = 0
            while q and inst < nslots[su]:
                h, i = heapq.heappop(q)
                s = ops[i]
                names = [n for n, _ in s.srcs]
                w = c + OPERAND_STAGES + s.lat
                dead = not users[s.dst] and s.dst not in needed
                own = units.slot_of(su, inst)
                if own >= nb:  # misc slot without a bank: the least loaded bank
                    own = min(range(nb), key=lambda b: (load[b], b))
                target = None
                if not dead:
                    prefs = []
                    if s.dst in commit_to:
                        prefs.append(bank_of[commit_to[s.dst]])
                    if len(users[s.dst]) >= SPREAD_FANOUT:
                        # a word many ops read: the bank least read so far
                        prefs += sorted(range(nb), key=lambda b: (load[b], b))
                    prefs.append(own)
                    prefs += sorted(range(nb), key=lambda b: (b != own, load[b], b))
                    # a write costs a shared bank a read port: the other banks first (after
                    # the bank of the register a temporary is committed to)
                    head = prefs[:1] if s.dst in commit_to else []
                    rest = prefs[1:] if head else prefs
                    prefs = (head + [b for b in rest if not shared(b)]
                             + [b for b in rest if shared(b)])
                    for b in prefs:
                        if write_free(w, b):
                            target = b
                            break
                if split:
                    swap = orient(c, s)
                    fits = swap is not None
                else:
                    fits = reads_fit(c, names)
                # the misc cores share one result bus into the banks: one result per cycle
                misc_busy = su == "misc" and ((w, "misc") in writes
                                              or c < core_free.get(s.unit, 0))
                if not fits or misc_busy or (not dead and target is None):
                    if not fits and reserved.get(i, -1) < c:
                        r = reserve(c, names)
                        if r is not None:
                            reserved[i] = r
                    skipped.append((h, i))
                    continue
                if split:
                    if swap:
                        _swap_sources(s)
                    take_ports(c, [n for n, _ in s.srcs])
                take_reads(c, names)
                s.issue, s.inst = c, (inst if su != "misc" else 0)
                issued.add((c, units.slot_of(su, inst)))
                if su == "misc":
                    writes.add((w, "misc"))
                    core_free[s.unit] = c + units.interval(s.unit)
                if not dead:
                    writes.add((w, target))
                    bank[s.dst] = target
                    load[target] += len(users[s.dst])
                s.bank = target
                inst += 1
                placed += 1
                for u in users[s.dst]:
                    npred[u.index] -= 1
                    if npred[u.index] == 0:
                        early = max(_ready(producer[n]) for n, _ in u.srcs if n in producer)
                        heapq.heappush(pending, (early, -u.height, u.index))
            for item in skipped:
                heapq.heappush(q, item)
        c += 1
    # commits: in place when the temporary sits in the register's bank and is written no
    # earlier than the register's last read; otherwise a mov on the misc slot
    last_read: dict = {}
    for s in ops:
        for name, _ in s.srcs:
            if name not in producer:
                last_read[name] = max(last_read.get(name, -1), s.issue)
    direct = {}
    movs = []
    for reg, tmp in prog.commit.items():
        if tmp not in producer:
            raise ScheduleError(f"{prog.name}: commit of {reg} from non-temporary {tmp}")
        p = producer[tmp]
        if (tmp not in direct and bank.get(tmp) == bank_of[reg]
                and p.write >= last_read.get(reg, -1)):
            direct[tmp] = reg
        else:
            movs.append((_ready(p), reg, tmp))
    lat_mov = units.latency("mov")
    misc_slot = units.slot_of("misc", 0)
    for early, reg, tmp in sorted(movs):
        c = max(early, last_read.get(reg, -1) - OPERAND_STAGES - lat_mov)
        while ((c, misc_slot) in issued
               or not write_free(c + OPERAND_STAGES + lat_mov, bank_of[reg])
               or (c + OPERAND_STAGES + lat_mov, "misc") in writes
               or not (ports_fit(c, [tmp]) if split else reads_fit(c, [tmp]))):
            c += 1
        issued.add((c, misc_slot))
        writes.add((c + OPERAND_STAGES + lat_mov, bank_of[reg]))
        writes.add((c + OPERAND_STAGES + lat_mov, "misc"))
        take_reads(c, [tmp])
        if split:
            take_ports(c, [tmp])
        s = BSOp(len(ops), reg, "mov", ((tmp, False),), "mov", 0, c)
        s.lat = lat_mov
        s.bank = bank_of[reg]
        ops.append(s)
    order = {"mul": 0, "add": 1}
    ops.sort(key=lambda s: (s.issue, order.get(s.unit, 2), s.inst))
    cycles = max(s.write for s in ops) + 1
    last_use: dict = {}
    for s in ops:
        for name, _ in s.srcs:
            if name in producer:
                last_use[name] = max(last_use.get(name, -1), s.issue)
    for tmp in prog.outputs.values():
        last_use[tmp] = cycles
    return ScheduledProgram(prog.name, ops, cycles, dict(prog.commit), dict(prog.outputs),
                            direct, last_use)


@dataclass
class BankedLayout:
    """Addresses of the banked register file shared by several programs. A register's
    host (flat) address is ``bank << local_bits | local``."""

    banks: int
    local_bits: int
    fixed: dict  #: persistent name -> flat address
    depth: int  #: flat address space (banks << local_bits)
    bank_depth: list  #: words used per bank
    temp_addr: dict  #: program name -> {temporary: flat address}
    const_init: dict  #: flat address -> bits
    temp_base: int = 0  #: persistent words (all banks)

    def split(self, flat: int) -> tuple:
        return flat >> self.local_bits, flat & ((1 << self.local_bits) - 1)


def assign_banks(names: list, units: BankedUnits, reads: dict | None = None) -> dict:
    """Persistent register -> bank: spread evenly, the most-read registers first (round
    robin in order of read counts, so that hot words do not share a bank)."""
    reads = reads or {}
    order = sorted(names, key=lambda n: (-reads.get(n, 0), names.index(n)))
    return {n: k % units.banks for k, n in enumerate(order)}


def allocate_banked(scheduled: dict, fixed_names: list, bank_of: dict,
                    units: BankedUnits) -> BankedLayout:
    nb = units.banks
    local: dict = {}
    count = [0] * nb
    for n in fixed_names:
        b = bank_of[n]
        local[n] = count[b]
        count[b] += 1
    base = list(count)
    temps: dict = {}
    top = [0] * nb
    for key, sp in scheduled.items():
        addr: dict = {}
        active = [[] for _ in range(nb)]
        free = [[] for _ in range(nb)]
        used = [0] * nb
        for s in sorted((s for s in sp.ops if s.kind != "mov"), key=lambda s: s.write):
            if s.dst in sp.direct:
                reg = sp.direct[s.dst]
                addr[s.dst] = (bank_of[reg], local[reg])
                continue
            if s.dst not in sp.last_use:
                continue
            b = s.bank
            while active[b] and active[b][0][0] < s.write:
                heapq.heappush(free[b], heapq.heappop(active[b])[1])
            slot = heapq.heappop(free[b]) if free[b] else used[b]
            used[b] = max(used[b], slot + 1)
            heapq.heappush(active[b], (sp.last_use[s.dst], slot))
            addr[s.dst] = (b, base[b] + slot)
        temps[key] = addr
        top = [max(t, u) for t, u in zip(top, used, strict=True)]
    depth = [base[b] + top[b] for b in range(nb)]
    lb = max(1, (max(depth) - 1).bit_length())
    fixed = {n: (bank_of[n] << lb) | local[n] for n in fixed_names}
    temp_addr = {k: {t: (b << lb) | a for t, (b, a) in v.items()} for k, v in temps.items()}
    const_init = {fixed[n]: int(n[2:], 16) for n in fixed_names if n.startswith("c:")}
    return BankedLayout(nb, lb, fixed, nb << lb, depth, temp_addr, const_init,
                        sum(base))


