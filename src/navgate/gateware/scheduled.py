"""Scheduled float32 datapath: a list scheduler for float32 op programs and an Amaranth
machine that executes the schedule on shared pipelined :mod:`navgate.gateware.fp32` cores.

Reference: the pattern of seed 004's scheduled datapath (:mod:`navgate.systems.kf2x2.schedule`,
resource-constrained list scheduling, control generated from the schedule), here for
pipelined float32 units and a register file; list scheduling with latency-weighted height
priority (Gajski et al., "High-Level Synthesis", 1992, ch. 7; De Micheli, "Synthesis and
Optimization of Digital Circuits", 1994, sec. 5.4). docs/seed000-engines.md describes it.

Programs
--------
A program is a list of ops with ``dst``, ``kind`` and ``srcs`` (SSA: every ``dst`` is a new
temporary), a ``commit`` map (register <- temporary, all reads of a register in the program
see its value at program start) and ``outputs`` (name -> temporary) -- the form of
:class:`navgate.systems.ins_trn.fp32_program.Program`. Kinds: ``add sub mul div sqrt le lt
cvt neg``; ``neg`` is a sign flip folded into its consumers' operand paths (it must feed
arithmetic ops only). Register names that are not temporaries are persistent: ``c:<hex>``
constants (initialised in the register file) and every name listed in ``fixed``.

Timing of one op issued in cycle ``c`` (every figure exact):

* cycle ``c``: its control word (registered microcode ROM output) presents the operand
  addresses to the register file's read ports (synchronous, non-transparent);
* cycle ``c + 1``: operands (sign-flipped where a ``neg`` was folded) enter the unit;
* cycle ``w = c + 1 + L`` (L: the core's ``LATENCY``): the unit's result is valid and the
  control word of cycle ``w`` writes it (write port of that unit instance) at the end of ``w``;
* the operand read ports are transparent to the units' write ports (a read in the cycle of
  a write to the same address returns the new word), so a read issued in cycle ``r`` sees
  the write iff ``w <= r``: results are ready ``L + 1`` cycles after issue, and a register
  may be overwritten only after the cycle of its last read.

Units: ``mul`` (Fp32Mul, 5), ``add`` (Fp32Add, add/sub, 8), ``div`` (30), ``sqrt`` (29),
``cmp`` (Fp32Compare, 2, result 1.0/0.0), ``cvt`` (Fp32FromInt(32): a register holding a
two's complement integer, 4) and ``mov`` (a one-cycle copy used for commits that cannot be
written in place). Every instance issues at most one op per cycle and has its own read and
write ports, so the only resource constraint is one issue per instance per cycle.

Commit: a committed temporary whose write cycle is not before the last read of its target
register is written straight into the target's address; otherwise a ``mov`` copies it
once both are allowed. Register allocation: temporaries share one region by lifetime
(interval from write to last read; outputs live to the end of the program); dead results
are not written.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass, field

from amaranth.hdl import Cat, Module, Mux, Signal, unsigned
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware.fp32 import Fp32Add, Fp32Compare, Fp32Div, Fp32FromInt, Fp32Mul, Fp32Sqrt

__all__ = ["UNIT_OF_KIND", "UNIT_LATENCY", "Units", "SOp", "ScheduledProgram", "ScheduleError",
           "schedule_program", "RegisterLayout", "MachineImage", "ScheduledMachine",
           "ONE_BITS", "QNAN_BITS", "ScheduledMachineStream", "CMD_WRITE", "CMD_READ", "CMD_START"]

UNIT_OF_KIND = {"add": "add", "sub": "add", "mul": "mul", "div": "div", "sqrt": "sqrt",
                "le": "cmp", "lt": "cmp", "cvt": "cvt", "mov": "mov"}
UNIT_LATENCY = {"add": Fp32Add.LATENCY, "mul": Fp32Mul.LATENCY, "div": Fp32Div.LATENCY,
                "sqrt": Fp32Sqrt.LATENCY, "cmp": Fp32Compare.LATENCY, "cvt": 4, "mov": 1}
UNIT_ORDER = ("mul", "add", "div", "sqrt", "cmp", "cvt", "mov")
N_SRCS = {"mul": 2, "add": 2, "div": 2, "sqrt": 1, "cmp": 2, "cvt": 1, "mov": 1}
ONE_BITS = 0x3F800000
QNAN_BITS = 0x7FC00000
#: issue -> readable: operand read (1) + unit latency (the write is bypassed to the reads)
OVERHEAD = 1


class ScheduleError(RuntimeError):
    """The program cannot be scheduled (unknown operand, unsupported neg use)."""


@dataclass(frozen=True)
class Units:
    """Instances of each unit class (classes a program does not use are not built)."""

    mul: int = 4
    add: int = 4
    div: int = 1
    sqrt: int = 1
    cmp: int = 1
    cvt: int = 1
    mov: int = 1

    def count(self, unit: str) -> int:
        return getattr(self, unit)


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

    @property
    def write(self) -> int:
        return self.issue + 1 + UNIT_LATENCY[self.unit]

    @property
    def ready(self) -> int:
        return self.issue + UNIT_LATENCY[self.unit] + OVERHEAD


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


def schedule_program(prog, units: Units, fixed) -> ScheduledProgram:
    """List-schedule ``prog`` onto ``units``; ``fixed``: names of persistent registers."""
    fixed = set(fixed)
    ops = _fold_negs(prog)
    producer = {s.dst: s for s in ops}
    for s in ops:
        s.unit = UNIT_OF_KIND[s.kind]
        if units.count(s.unit) < 1:
            raise ScheduleError(f"{prog.name}: no {s.unit} unit for {s.kind}")
        for name, _ in s.srcs:
            if name not in producer and name not in fixed and not name.startswith("c:"):
                raise ScheduleError(f"{prog.name}: unknown operand {name} of {s.dst}")
    users: dict = {s.dst: [] for s in ops}
    for s in ops:
        for name, _ in s.srcs:
            if name in users:
                users[name].append(s)
    for s in reversed(ops):
        lat = UNIT_LATENCY[s.unit] + OVERHEAD
        s.height = lat + max((u.height for u in users[s.dst]), default=0)
    npred = {s.index: len({n for n, _ in s.srcs if n in producer}) for s in ops}
    pending = []  # (earliest, -height, index)
    for s in ops:
        if npred[s.index] == 0:
            heapq.heappush(pending, (0, -s.height, s.index))
    ready = {u: [] for u in UNIT_ORDER}
    placed = 0
    c = 0
    while placed < len(ops):
        while pending and pending[0][0] <= c:
            _, h, i = heapq.heappop(pending)
            heapq.heappush(ready[ops[i].unit], (h, i))
        for unit in UNIT_ORDER:
            q = ready[unit]
            for inst in range(units.count(unit)):
                if not q:
                    break
                _, i = heapq.heappop(q)
                s = ops[i]
                s.issue, s.inst = c, inst
                placed += 1
                seen = set()
                for u in users[s.dst]:
                    if u.index in seen:
                        continue
                    seen.add(u.index)
                    npred[u.index] -= 1
                    if npred[u.index] == 0:
                        early = max(producer[n].ready for n, _ in u.srcs if n in producer)
                        heapq.heappush(pending, (early, -u.height, u.index))
        c += 1
    # commit: in place when allowed, else a mov
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
        if producer[tmp].write > last_read.get(reg, -1) and tmp not in direct:
            direct[tmp] = reg
        else:
            early = max(producer[tmp].ready, last_read.get(reg, -1) - UNIT_LATENCY["mov"])
            movs.append((early, reg, tmp))
    busy: set = set()
    for early, reg, tmp in sorted(movs):
        c = early
        while (c, 0) in busy:
            c += 1
        busy.add((c, 0))
        s = SOp(len(ops), reg, "mov", ((tmp, False),), "mov", 0, c)
        ops.append(s)
    ops.sort(key=lambda s: (s.issue, UNIT_ORDER.index(s.unit), s.inst))
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
class RegisterLayout:
    """Addresses of the register file shared by several programs."""

    fixed: dict  #: persistent name -> address
    temp_base: int
    depth: int
    temp_addr: dict  #: program name -> {temporary: address}
    const_init: dict  #: address -> bits


def allocate(scheduled: dict, fixed_names) -> RegisterLayout:
    """Persistent registers first (``fixed_names`` then constants), temporaries above them,
    allocated per program by lifetime (left-edge on write cycles)."""
    names = list(dict.fromkeys(fixed_names))
    consts = sorted({n for sp in scheduled.values() for s in sp.ops for n, _ in s.srcs
                     if n.startswith("c:")})
    fixed = {n: i for i, n in enumerate(names + consts)}
    const_init = {fixed[c]: int(c[2:], 16) for c in consts}
    base = len(fixed)
    temp_addr = {}
    top = 0
    for key, sp in scheduled.items():
        addr: dict = {}
        active: list = []  # (last_use, slot)
        free: list = []
        nslots = 0
        for s in sorted((s for s in sp.ops if s.kind != "mov"), key=lambda s: s.write):
            if s.dst in sp.direct:
                addr[s.dst] = fixed[sp.direct[s.dst]]
                continue
            if s.dst not in sp.last_use:
                continue  # dead: not written
            while active and active[0][0] < s.write:
                heapq.heappush(free, heapq.heappop(active)[1])
            slot = heapq.heappop(free) if free else nslots
            nslots = max(nslots, slot + 1)
            heapq.heappush(active, (sp.last_use[s.dst], slot))
            addr[s.dst] = base + slot
        temp_addr[key] = addr
        top = max(top, nslots)
    depth = base + top
    return RegisterLayout(fixed, base, depth, temp_addr, const_init)


class _Fields:
    """Bit positions of the control word."""

    def __init__(self, units: dict, aw: int):
        self.aw = aw
        self.pos: dict = {}
        off = 0
        for unit, n in units.items():
            for k in range(n):
                spec = [("iss", 1), ("mod", 1), ("wmod", 1), ("we", 1), ("wa", aw)]
                for j in range(N_SRCS[unit]):
                    spec += [(f"s{j}", aw), (f"f{j}", 1)]
                for name, w in spec:
                    self.pos[(unit, k, name)] = (off, w)
                    off += w
        self.width = off


@dataclass
class MachineImage:
    """Everything the gateware is generated from: schedules, register layout, microcode."""

    units: dict  #: unit -> instances built
    programs: dict  #: name -> ScheduledProgram
    layout: RegisterLayout
    base: dict  #: program name -> first ROM row
    rom: list  #: control words
    fields: _Fields

    @classmethod
    def build(cls, programs: dict, units: Units, fixed_names) -> MachineImage:
        fixed_names = list(fixed_names)
        sched = {k: schedule_program(p, units, fixed_names) for k, p in programs.items()}
        used = {s.unit for sp in sched.values() for s in sp.ops}
        ucount = {u: units.count(u) for u in UNIT_ORDER if u in used}
        layout = allocate(sched, fixed_names)
        aw = max(1, (layout.depth - 1).bit_length())
        f = _Fields(ucount, aw)
        rom: list = []
        base = {}
        for key, sp in sched.items():
            base[key] = len(rom)
            rows = [0] * sp.cycles
            addr = dict(layout.fixed)
            addr.update(layout.temp_addr[key])

            def put(row, unit, inst, name, value, rows=rows):
                off, w = f.pos[(unit, inst, name)]
                assert 0 <= value < (1 << w)
                rows[row] |= value << off

            for s in sp.ops:
                put(s.issue, s.unit, s.inst, "iss", 1)
                for j, (name, flip) in enumerate(s.srcs):
                    put(s.issue, s.unit, s.inst, f"s{j}", addr[name])
                    put(s.issue, s.unit, s.inst, f"f{j}", int(flip))
                if s.kind == "sub":
                    put(s.issue, s.unit, s.inst, "mod", 1)
                if s.kind == "le":
                    put(s.write, s.unit, s.inst, "wmod", 1)
                dst = layout.fixed[s.dst] if s.kind == "mov" else addr.get(s.dst)
                if dst is not None:
                    put(s.write, s.unit, s.inst, "we", 1)
                    put(s.write, s.unit, s.inst, "wa", dst)
            rom += rows
        return cls(ucount, sched, layout, base, rom, f)

    def cycles(self, key: str) -> int:
        return self.programs[key].cycles

    def output_addr(self, key: str) -> dict:
        sp = self.programs[key]
        return {n: self.layout.temp_addr[key][t] for n, t in sp.outputs.items()}

    def machine(self, init: dict | None = None):
        return ScheduledMachine(self, init)


class _Mov(wiring.Component):
    """One-cycle register (the commit copy)."""

    LATENCY = 1

    def __init__(self):
        super().__init__({"a": In(32), "valid_i": In(1), "r": Out(32), "valid_o": Out(1)})

    def elaborate(self, platform):
        m = Module()
        m.d.sync += [self.r.eq(self.a), self.valid_o.eq(self.valid_i)]
        return m


class ScheduledMachine(wiring.Component):
    """Executes the programs of a :class:`MachineImage`.

    Ports: ``start`` with ``prog`` (program number, in the image's order) while not ``busy``
    starts a program (its first issue cycle is the next cycle); ``done`` is high for one
    cycle after its last write, exactly ``cycles(prog) + 1`` cycles after ``start``.
    Host access while idle: ``host_we``/``host_waddr``/``host_wdata`` write a register,
    ``host_raddr`` -> ``host_rdata`` (one cycle later) reads one. ``LATENCY``: per program,
    ``cycles + 1``; ``THROUGHPUT``: one program at a time.
    """

    def __init__(self, image: MachineImage, init: dict | None = None):
        self.image = image
        self.init = dict(init or {})  #: address -> bits (initial register file contents)
        aw = image.fields.aw
        self.keys = list(image.programs)
        super().__init__({
            "start": In(1), "prog": In(range(max(2, len(self.keys)))),
            "busy": Out(1), "done": Out(1),
            "host_we": In(1), "host_waddr": In(aw), "host_wdata": In(32),
            "host_raddr": In(aw), "host_rdata": Out(32),
        })

    def elaborate(self, platform):
        m = Module()
        img = self.image
        f = img.fields
        aw = f.aw
        init = [0] * img.layout.depth
        for a, v in img.layout.const_init.items():
            init[a] = v
        for a, v in self.init.items():
            init[a] = v
        m.submodules.regs = regs = Memory(shape=unsigned(32), depth=img.layout.depth,
                                          init=init)
        m.submodules.rom = rom = Memory(shape=unsigned(f.width), depth=len(img.rom),
                                        init=img.rom)
        # sequencer
        rw = max(1, (len(img.rom) - 1).bit_length())
        pc = Signal(rw)
        last = Signal(rw)
        running = Signal()
        bases = [img.base[k] for k in self.keys]
        lasts = [img.base[k] + img.programs[k].cycles - 1 for k in self.keys]
        base_sel = Signal(rw)
        last_sel = Signal(rw)
        with m.Switch(self.prog):
            for i in range(len(self.keys)):
                with m.Case(i):
                    m.d.comb += [base_sel.eq(bases[i]), last_sel.eq(lasts[i])]
        rp = rom.read_port()
        go = Signal()
        m.d.comb += [go.eq(self.start & ~running), self.busy.eq(running)]
        nxt = Signal(rw)
        m.d.comb += nxt.eq(Mux(go, base_sel, Mux(running & (pc != last), pc + 1, pc)))
        m.d.comb += rp.addr.eq(nxt)
        done = Signal()
        with m.If(go):
            m.d.sync += [running.eq(1), pc.eq(base_sel), last.eq(last_sel)]
        with m.Elif(running):
            m.d.sync += pc.eq(nxt)
            with m.If(pc == last):
                m.d.sync += running.eq(0)
        m.d.comb += done.eq(running & (pc == last))
        m.d.sync += self.done.eq(done)
        ctl = Signal(f.width)
        m.d.comb += ctl.eq(Mux(running, rp.data, 0))

        def fld(unit, k, name):
            off, w = f.pos[(unit, k, name)]
            return ctl[off:off + w]

        hw = regs.write_port()
        m.d.comb += [hw.en.eq(self.host_we & ~running), hw.addr.eq(self.host_waddr),
                     hw.data.eq(self.host_wdata)]
        hr = regs.read_port()
        m.d.comb += [hr.addr.eq(self.host_raddr), self.host_rdata.eq(hr.data)]

        wports = {}
        for unit, n in img.units.items():
            for k in range(n):
                wp = regs.write_port()
                m.d.comb += [wp.en.eq(fld(unit, k, "we")), wp.addr.eq(fld(unit, k, "wa"))]
                wports[(unit, k)] = wp
        for unit, n in img.units.items():
            for k in range(n):
                name = f"{unit}{k}"
                ops = []
                for j in range(N_SRCS[unit]):
                    p = regs.read_port(transparent_for=tuple(wports.values()))
                    m.d.comb += p.addr.eq(fld(unit, k, f"s{j}"))
                    flip = Signal(name=f"{name}_f{j}")
                    m.d.sync += flip.eq(fld(unit, k, f"f{j}"))
                    v = Signal(32, name=f"{name}_op{j}")
                    m.d.comb += v.eq(p.data ^ Cat(Signal(31), flip))
                    ops.append(v)
                valid = Signal(name=f"{name}_valid")
                mod = Signal(name=f"{name}_mod")
                m.d.sync += [valid.eq(fld(unit, k, "iss")), mod.eq(fld(unit, k, "mod"))]
                res = Signal(32, name=f"{name}_res")
                if unit == "mov":
                    core = _Mov()
                    m.d.comb += [core.a.eq(ops[0]), core.valid_i.eq(valid), res.eq(core.r)]
                else:
                    core = {"mul": Fp32Mul, "add": Fp32Add, "div": Fp32Div, "sqrt": Fp32Sqrt,
                            "cmp": Fp32Compare, "cvt": lambda: Fp32FromInt(32)}[unit]()
                    m.d.comb += [core.i.valid.eq(valid), core.o.ready.eq(1)]
                    if unit == "cvt":
                        m.d.comb += core.i.payload.x.eq(ops[0])
                    elif unit == "sqrt":
                        m.d.comb += core.i.payload.a.eq(ops[0])
                    else:
                        m.d.comb += [core.i.payload.a.eq(ops[0]), core.i.payload.b.eq(ops[1])]
                    if unit == "add":
                        m.d.comb += core.i.payload.sub.eq(mod)
                    if unit == "cmp":
                        o = core.o.payload
                        flag = o.lt | (fld(unit, k, "wmod") & o.equal)
                        m.d.comb += res.eq(Mux(flag, ONE_BITS, 0))
                    else:
                        m.d.comb += res.eq(core.o.payload.r)
                m.submodules[name] = core
                m.d.comb += wports[(unit, k)].data.eq(res)
        del aw
        return m


CMD_WRITE, CMD_READ, CMD_START = 0, 1, 2


class ScheduledMachineStream(wiring.Component):
    """The machine of ``image`` (:class:`ScheduledMachine`, or the banked machine of
    :mod:`navgate.gateware.banked`) behind one command stream (for the verification harness and
    the ``rtl`` engine). Input payload ``{cmd, addr, data, prog}``: ``cmd`` 0 writes ``data``
    to register ``addr``, 1 reads register ``addr``, 2 runs program ``prog``. One output
    ``{data, cycles}`` per command: the word read (0 otherwise) and, for a run, the cycles
    from start to done (``cycles(prog) + 1``). A write or read takes 2 cycles + the
    handshake, a run ``cycles + 2``."""

    LATENCY = 3
    THROUGHPUT = 0.5

    def __init__(self, image: MachineImage, init: dict | None = None):
        from amaranth.lib import data, stream

        self.image = image
        self.init = init
        aw = image.fields.aw
        pw = max(1, (len(image.programs) - 1).bit_length())
        self.in_layout = data.StructLayout({"cmd": 2, "addr": aw, "data": 32, "prog": pw})
        self.out_layout = data.StructLayout({"data": 32, "cycles": 16})
        super().__init__({"i": In(stream.Signature(self.in_layout)),
                          "o": Out(stream.Signature(self.out_layout))})

    def elaborate(self, platform):
        m = Module()
        core = self.image.machine(self.init)
        m.submodules.core = core
        res = Signal(32)
        cyc = Signal(16)
        p = self.i.payload
        m.d.comb += [core.host_waddr.eq(p.addr), core.host_wdata.eq(p.data),
                     core.host_raddr.eq(p.addr), core.prog.eq(p.prog),
                     self.o.payload.data.eq(res), self.o.payload.cycles.eq(cyc)]
        with m.FSM():
            with m.State("IDLE"):
                m.d.comb += self.i.ready.eq(1)
                with m.If(self.i.valid):
                    with m.Switch(p.cmd):
                        with m.Case(CMD_WRITE):
                            m.d.comb += core.host_we.eq(1)
                            m.d.sync += [res.eq(0), cyc.eq(0)]
                            m.next = "RESP"
                        with m.Case(CMD_READ):
                            m.d.sync += cyc.eq(0)
                            m.next = "READ"
                        with m.Default():
                            m.d.comb += core.start.eq(1)
                            m.d.sync += [res.eq(0), cyc.eq(1)]
                            m.next = "RUN"
            with m.State("READ"):
                m.d.sync += res.eq(core.host_rdata)
                m.next = "RESP"
            with m.State("RUN"):
                m.d.sync += cyc.eq(cyc + 1)
                with m.If(core.done):
                    m.d.sync += cyc.eq(cyc)
                    m.next = "RESP"
            with m.State("RESP"):
                m.d.comb += self.o.valid.eq(1)
                with m.If(self.o.ready):
                    m.next = "IDLE"
        return m
