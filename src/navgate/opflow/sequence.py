"""Sequences of loop nests on one shared datapath: the program (named segments over shared
memories, entry points), its bit-true executor, its schedules and the sequence machine in
Amaranth.

A :class:`SequenceProgram` names its float32 memories once (``arrays``: name -> words) and
holds ``segments`` (name -> :class:`~navgate.opflow.loops.LoopNest`; a straight-line segment
is a nest with ``trips == ()``, one iteration) whose arrays are among the program's, with
the same sizes, and ``entries`` (name -> ordered segment names, e.g. "propagate",
"update"). An entry runs its segments in order; each reads the memories as the segments
before it left them (:func:`run_sequence`, built on :func:`~navgate.opflow.loops.run_nest`).

:func:`schedule_sequence` modulo-schedules every segment (:func:`~navgate.opflow.loops.
modulo_schedule`) on the same units: ``lanes`` (1 to 4) float32 multipliers and as many
adders, one iterative divider, one iterative square root and one comparator, ``read_ports``
read ports per memory.

:class:`SequenceMachine` (the loop machine of :mod:`navgate.opflow.loopmachine` grown into
an engine; its timing rules are those of :mod:`navgate.opflow.loops`) runs any entry on ONE
datapath:

* **units**, built once (by default, :func:`schedule_sequence` ``registered``, behind a
  register stage that holds their operands, and the memories' words registered once):
  ``lanes`` x (:class:`~navgate.gateware.fp32.Fp32Mul`,
  :class:`~navgate.gateware.fp32.Fp32Add`), and where a segment uses them
  :class:`~navgate.gateware.fp32.Fp32DivIter`, :class:`~navgate.gateware.fp32.Fp32SqrtIter`
  (started only by an issued iteration: ``i.valid`` is the iteration's valid bit) and
  :class:`~navgate.gateware.fp32.Fp32Compare` (its ``lt``/``equal`` bits ride the delay line,
  a ``lt``/``le`` consumer turns them into 1.0 or 0.0); every unit output and memory read port
  feeds a delay line, an operand is a tap of one (its age fixed by the schedule);
* **memories**: one :class:`amaranth.lib.memory.Memory` per program array, shared by every
  segment (32-bit words, synchronous reads, one write port); Yosys maps small ones to LUT
  RAM or registers and large ones to block RAM;
* **control store**: one ROM row per (segment, phase modulo the segment's II), read
  combinationally at ``base[segment] + phase``; a row holds, for every control point (an
  operand of a unit, an adder's subtract bit, a divider's start, a read address, a write
  enable, address and data), the index of its source among the sources that point ever takes
  in the program (tap, constant, accumulator multiplexer, sign flip, address or flag delay
  line). The rows grow with the sum of the segments' IIs (the program text), the multiplexers
  with the distinct sources;
* **sequencer**: an entry ROM (the flattened segment lists; ``entry`` selects the first
  position at ``start``), per-segment constants (iterations, II, depth, trip counts of the
  levels, padded on the outside with trips of 1, control-store base), shared level counters,
  address generators (slot ``k`` of a segment is its ``k``-th distinct address; strength
  reduced index registers with per-segment offsets and increments, or ROM tables indexed by
  them; an address that is the same in every iteration, as every address of a straight-line
  segment, is a constant source of its read or write port instead) and flag generators
  (level conditions, ROM flag tables); each segment's iteration
  valid bits clear at its start, so no write of one segment can fire in another;
* **host port** as the loop machine's: while idle, read port 0 and the write port of each
  memory serve ``host_addr`` (array number << ``array_bits`` | word); written words are
  flushed (a subnormal becomes the zero of its sign), as :func:`run_sequence` reads its
  memories, so a word written and never computed on reads back as the executor's.

Handshake: ``start`` (one cycle, while ``busy`` is low; ``entry`` = the entry's number,
:meth:`SequenceMachine.entry_index`; an unknown number is ignored) runs the entry; segment
``k`` issues in the cycle after segment ``k - 1``'s last cycle (the last iteration's offset
``depth - 1``, its last write: segment ``k`` reads no word before its offset ``ADDR_READY``,
and the iterative units are free again, their interval being shorter than their latency),
and ``done`` is high for one cycle :meth:`SequenceSchedule.cycles` cycles after the start
cycle: the sum over the entry's segments of their schedule cycles, + 1 (``done`` comes one
cycle after the last write, so the host reads the written words from the cycle after it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from amaranth.hdl import Cat, Const, Module, Mux, Signal, unsigned
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware.fp32 import Fp32Add, Fp32Compare, Fp32DivIter, Fp32Mul, Fp32SqrtIter
from navgate.opflow.loopmachine import delay_tap, simulate_entries, to_bits
from navgate.opflow.loops import (
    Addr,
    CompiledNest,
    LoopError,
    LoopNest,
    LoopSchedule,
    LoopUnits,
    addresses,
    check_nest,
    iteration_indices,
    modulo_schedule,
    run_nest,
)

__all__ = ["SequenceProgram", "SequenceSchedule", "SequenceMachine", "check_sequence",
           "run_sequence", "schedule_sequence", "simulate_sequence", "MAX_LANES"]

MAX_LANES = 4
ONE = 0x3F800000
QNAN = 0x7FC00000


@dataclass
class SequenceProgram:
    name: str
    arrays: dict  #: name -> words, shared by every segment
    segments: dict  #: name -> LoopNest
    entries: dict  #: name -> tuple of segment names, run in order


def check_sequence(prog: SequenceProgram) -> None:
    """Raise :class:`LoopError` for a malformed program (and for a malformed segment)."""
    if not prog.entries:
        raise LoopError(f"{prog.name}: no entry points")
    for name, words in prog.arrays.items():
        if int(words) < 1:
            raise LoopError(f"{prog.name}: array {name} needs at least one word")
    for sname, nest in prog.segments.items():
        for a, words in nest.arrays.items():
            if prog.arrays.get(a) != words:
                raise LoopError(f"{prog.name}: segment {sname} has array {a} of {words} words, "
                                f"the program {prog.arrays.get(a, 'none')}")
        check_nest(nest)
    for ename, segs in prog.entries.items():
        if not segs:
            raise LoopError(f"{prog.name}: entry {ename} runs no segment")
        for s in segs:
            if s not in prog.segments:
                raise LoopError(f"{prog.name}: entry {ename} names unknown segment {s}")


def _flushed(prog, memories):
    mem = {}
    for name, words in prog.arrays.items():
        v = np.asarray(memories.get(name, np.zeros(words)))
        if v.dtype == np.uint32:
            v = v.view(np.float32)
        if v.shape != (words,):
            raise LoopError(f"{prog.name}: memory {name} needs {words} words")
        mem[name] = v.astype(np.float32).astype(np.float64)
    return mem


def run_sequence(prog: SequenceProgram, memories: dict, entry: str,
                 compiled: dict | None = None) -> dict:
    """Run entry ``entry`` on ``memories`` (array -> float32 values or uint32 patterns;
    missing arrays are zeros): returns every array after it (float64 holding float32),
    inputs untouched. ``compiled`` (segment -> CompiledNest) may cache the lowered nests."""
    if entry not in prog.entries:
        raise LoopError(f"{prog.name}: unknown entry {entry!r}; known: {', '.join(prog.entries)}")
    mem = _flushed(prog, memories)
    for sname in prog.entries[entry]:
        nest = prog.segments[sname]
        c = compiled.get(sname) if compiled is not None else None
        if c is None:
            c = CompiledNest(nest)
            if compiled is not None:
                compiled[sname] = c
        mem.update(run_nest(c, {a: mem[a] for a in nest.arrays}))
    return mem


@dataclass
class SequenceSchedule:
    program: SequenceProgram
    lanes: int
    units: LoopUnits
    schedules: dict  #: segment -> LoopSchedule

    def cycles(self, entry: str) -> int:
        """Cycles from the start cycle to ``done`` for ``entry``."""
        return sum(self.schedules[s].cycles for s in self.program.entries[entry]) + 1

    @property
    def control_rows(self) -> int:
        return sum(s.ii for s in self.schedules.values())


def schedule_sequence(prog: SequenceProgram, lanes: int = 1, read_ports: int = 2,
                      registered: bool = True, result_ports: int = 0,
                      transfers: int = 0, late: str = "") -> SequenceSchedule:
    """Modulo-schedule every segment on ``lanes`` multipliers and adders (module docstring);
    ``registered``: memory words registered after the read (load latency 2) and one register
    stage between the operand multiplexers and the units (every unit one cycle longer), which
    keep block-RAM outputs and multiplexers off the units' first stages. ``result_ports``
    (a what-if, not this machine's: its delay lines take every result): at most that many
    unit results land in a cycle, as a register file's write ports would allow (0: no
    limit). ``transfers`` (a what-if too): the lanes as clusters, each taking that many
    values a cycle from the others (:attr:`~navgate.opflow.loops.LoopUnits.transfers`;
    0: no clusters);
    ``late`` (a what-if): ``"loads"`` or ``"all"`` ops as late as their reads allow
    (:attr:`~navgate.opflow.loops.LoopUnits.late`)."""
    if type(lanes) is not int or not 1 <= lanes <= MAX_LANES:
        raise LoopError(f"lanes must be an integer from 1 to {MAX_LANES}, got {lanes!r}")
    check_sequence(prog)
    units = LoopUnits(mul=lanes, add=lanes, read_ports=read_ports,
                      load_latency=2 if registered else 1, operand_stage=int(registered),
                      result_ports=result_ports, transfers=transfers,
                      late=late)
    return SequenceSchedule(prog, lanes, units,
                            {n: modulo_schedule(nest, units) for n, nest in
                             prog.segments.items()})


def _bits(n: int) -> int:
    return max(1, int(n - 1).bit_length())


def _neg(m, v):
    """Sign flip as :func:`navgate.numerics.fp32.fp32_neg`: NaN -> canonical NaN, a subnormal
    -> the zero of the flipped sign."""
    out = Signal(32, name="neg")
    exp, mant = v[23:31], v[:23]
    m.d.comb += out.eq(Mux((exp == 0xFF) & (mant != 0), QNAN,
                           Mux(exp == 0, Cat(Const(0, 31), ~v[31]),
                               Cat(v[:31], ~v[31]))))
    return out


def _fixed(ad: Addr) -> bool:
    """The address is the same in every iteration (no table, no stride): e.g. every address
    of a straight-line segment."""
    return ad.table is None and not any(ad.strides)


def _padded(nest: LoopNest, levels: int):
    """(pad, trips) of a nest seen with ``levels`` levels: ``pad`` outer levels of trip 1
    added."""
    pad = levels - len(nest.trips)
    return pad, (1,) * pad + tuple(nest.trips)


class SequenceMachine(wiring.Component):
    """The machine of a scheduled sequence program (module docstring)."""

    def __init__(self, schedule: SequenceSchedule, init: dict | None = None):
        self.schedule = schedule
        prog = schedule.program
        init = init or {}
        self.entries = list(prog.entries)
        self.arrays = list(prog.arrays)
        self.memories = {name: Memory(shape=unsigned(32), depth=words,
                                      init=to_bits(init.get(name, np.zeros(words, np.uint32))))
                         for name, words in prog.arrays.items()}
        self.array_bits = _bits(max(prog.arrays.values()))
        aw = self.array_bits + _bits(len(self.arrays))
        super().__init__({"start": In(1), "entry": In(_bits(len(self.entries))),
                          "busy": Out(1), "done": Out(1),
                          "host_addr": In(aw), "host_wdata": In(32), "host_we": In(1),
                          "host_rdata": Out(32)})

    def host_address(self, array: str, word: int) -> int:
        return self.arrays.index(array) << self.array_bits | word

    def entry_index(self, entry: str) -> int:
        return self.entries.index(entry)

    def elaborate(self, platform):  # noqa: C901 - one generator, read top to bottom
        m = Module()
        sch = self.schedule
        prog = sch.program
        segs = list(prog.segments)
        scheds: list[LoopSchedule] = [sch.schedules[n] for n in segs]
        nests = [prog.segments[n] for n in segs]
        levels = max(len(n.trips) for n in nests)
        dmax = max(s.depth for s in scheds)
        for name, mem in self.memories.items():
            m.submodules[f"mem_{name}"] = mem

        # ---- entry ROM and per-segment constants --------------------------------------
        flat, first, last = [], [], []
        for e in self.entries:
            first.append(len(flat))
            flat += [segs.index(s) for s in prog.entries[e]]
            last += [0] * (len(prog.entries[e]) - 1) + [1]

        def table(sel, values, name, width=None):
            width = width or _bits(max(int(v) for v in values) + 1)
            sig = Signal(width, name=name)
            with m.Switch(sel):
                for k, v in enumerate(values):
                    with m.Case(k):
                        m.d.comb += sig.eq(int(v) % (1 << width))
            return sig

        running = Signal()
        pos = Signal(range(len(flat)))
        seg = table(pos, flat, "seg", _bits(len(segs)))
        is_last_pos = table(pos, last, "last_pos", 1)
        start_now = Signal()
        entry_ok = self.entry < len(self.entries)
        m.d.comb += [start_now.eq(self.start & ~running & entry_ok), self.busy.eq(running)]
        left = Signal(range(max(n.iterations for n in nests) + 1))
        phase = Signal(_bits(max(s.ii for s in scheds)))
        nidx = Signal(_bits(max(n.iterations for n in nests)))
        ctr = [Signal(_bits(max(_padded(n, levels)[1][lv] for n in nests)), name=f"ctr{lv}")
               for lv in range(levels)]
        ii_m1 = table(seg, [s.ii - 1 for s in scheds], "ii_m1")
        base = [0]
        for s in scheds[:-1]:
            base.append(base[-1] + s.ii)
        rom_base = table(seg, base, "ctl_base", _bits(sch.control_rows))
        trips_m1 = [table(seg, [_padded(n, levels)[1][lv] - 1 for n in nests], f"trip_m1_{lv}")
                    for lv in range(levels)]
        issue = Signal()
        m.d.comb += issue.eq(running & (left != 0) & (phase == 0))
        iv = [issue]  # iv[k]: an iteration of this segment was issued k cycles ago
        for k in range(1, dmax + 1):
            v = Signal(name=f"iv{k}")
            m.d.sync += v.eq(iv[-1])
            iv.append(v)
        # a segment is done in the cycle of its last iteration's offset depth - 1 (its last
        # write) when another segment follows, which then issues in the next cycle: nothing
        # of the segment is left to read or write then; the entry's last segment one cycle
        # later, so that ``done`` follows the last write as the host port expects
        mask = table(seg, [sum(1 << (k - 1) for k in range(1, s.depth - 1)) for s in scheds],
                     "pending_mask", max(1, dmax - 1))
        mask_end = table(seg, [1 << (s.depth - 2) if s.depth >= 2 else 0 for s in scheds],
                         "pending_end", max(1, dmax - 1))
        ivs = Cat(*iv[1:dmax])
        # back to back: a divide or square root of the segment before is over by then
        assert all(c.INTERVAL <= c.LATENCY + 1 for c in (Fp32DivIter, Fp32SqrtIter))
        pending = (((ivs & mask) != 0) | (is_last_pos & ((ivs & mask_end) != 0))
                   if dmax > 1 else Const(0, 1))
        seg_done = Signal()
        m.d.comb += [seg_done.eq(running & (left == 0) & ~pending),
                     self.done.eq(seg_done & is_last_pos)]
        load = Signal()
        m.d.comb += load.eq(start_now | (seg_done & ~is_last_pos))
        entry_pos = table(self.entry, first, "entry_pos", len(pos))
        next_pos = Signal.like(pos)
        m.d.comb += next_pos.eq(Mux(start_now, entry_pos, pos + 1))
        next_seg = table(next_pos, flat, "next_seg", _bits(len(segs)))
        n_iter = table(next_seg, [n.iterations for n in nests], "n_iter", len(left))

        with m.If(running):
            m.d.sync += phase.eq(Mux(phase == ii_m1, 0, phase + 1))
        with m.If(issue):
            m.d.sync += [left.eq(left - 1), nidx.eq(nidx + 1)]
        is_last = [ctr[lv] == trips_m1[lv] for lv in range(levels)]

        def deeper_last(lv):
            return Cat(*is_last[lv + 1:]).all() if lv + 1 < levels else Const(1, 1)

        with m.If(issue):
            for lv in range(levels):
                with m.If(deeper_last(lv)):
                    m.d.sync += ctr[lv].eq(Mux(is_last[lv], 0, ctr[lv] + 1))
        with m.If(self.done):
            m.d.sync += running.eq(0)

        # ---- address and flag slots ------------------------------------------------------
        addr_slot: list[dict] = []  # per segment: Addr -> slot
        flag_slot: list[dict] = []  # per segment: Cond -> slot
        for n in nests:
            a: dict = {}
            for op in n.ops:
                if op.kind == "load" and not _fixed(op.addr):
                    a.setdefault(op.addr, len(a))
            for st in n.stores:
                if not _fixed(st.addr):
                    a.setdefault(st.addr, len(a))
            addr_slot.append(a)
            f: dict = {}
            for acc in n.accs:
                f.setdefault(acc.reset, len(f))
            for st in n.stores:
                if st.when is not None:
                    f.setdefault(st.when, len(f))
            flag_slot.append(f)
        idxs = [iteration_indices(n) for n in nests]
        addr_out = []
        for k in range(max((len(a) for a in addr_slot), default=0)):
            users = [(si, ad) for si, a in enumerate(addr_slot) for ad, kk in a.items()
                     if kk == k]
            lin = {si: addresses(nests[si], Addr(None, ad.strides, ad.offset), idxs[si])
                   for si, ad in users}
            iw = max(_bits(int(v.max()) + 1) for v in lin.values()) + 1
            reg = Signal(iw, name=f"ag{k}")
            offsets = [0] * len(nests)
            deltas = [[0] * len(nests) for _ in range(levels)]
            for si, ad in users:
                pad, trips = _padded(nests[si], levels)
                strides = [0] * pad + (list(ad.strides) or [0] * len(nests[si].trips))
                offsets[si] = ad.offset
                for lv in range(levels):
                    deltas[lv][si] = (strides[lv] - sum(strides[q] * (trips[q] - 1)
                                                        for q in range(lv + 1, levels)))
            off = table(next_seg, offsets, f"ag{k}_off", iw)
            dl = [table(seg, deltas[lv], f"ag{k}_d{lv}", iw) for lv in range(levels)]
            with m.If(issue):
                for lv in reversed(range(levels)):
                    with m.If(deeper_last(lv) & ~is_last[lv]):
                        m.d.sync += reg.eq(reg + dl[lv])
            with m.If(load):
                m.d.sync += reg.eq(off)
            reg_q = Signal(iw, name=f"ag{k}_q")
            m.d.sync += reg_q.eq(reg)
            widths = [iw]
            srcs = {}
            for si, ad in users:
                if ad.table is None:
                    srcs[si] = reg_q
                    continue
                tab = [int(x) for x in nests[si].tables[ad.table]]
                rom = Memory(shape=unsigned(_bits(max(tab) + 1)), depth=len(tab), init=tab)
                m.submodules[f"rom_ag{k}_s{si}_{ad.table}"] = rom
                rp = rom.read_port()
                m.d.comb += rp.addr.eq(reg)
                srcs[si] = rp.data
                widths.append(len(rp.data))
            out = Signal(max(widths), name=f"ai{k}")
            with m.Switch(seg):
                for si, sig in srcs.items():
                    with m.Case(si):
                        m.d.comb += out.eq(sig)
            addr_out.append(out)
        flag_out = []
        for k in range(max((len(f) for f in flag_slot), default=0)):
            users = [(si, c) for si, f in enumerate(flag_slot) for c, kk in f.items()
                     if kk == k]
            now = Signal(name=f"fl{k}_now")
            lvl = Signal(name=f"fl{k}_q")
            out = Signal(name=f"fl{k}")
            m.d.sync += lvl.eq(now)
            with m.Switch(seg):
                for si, c in users:
                    with m.Case(si):
                        if c.kind == "table":
                            tab = [int(x != 0) for x in nests[si].tables[c.arg]]
                            rom = Memory(shape=unsigned(1), depth=len(tab), init=tab)
                            m.submodules[f"rom_fl{k}_s{si}_{c.arg}"] = rom
                            rp = rom.read_port()
                            m.d.comb += [rp.addr.eq(nidx), out.eq(rp.data)]
                        else:
                            pad = _padded(nests[si], levels)[0]
                            lv = int(c.arg) + pad
                            upto = lv + 1 if c.kind.startswith("at_") else levels
                            want = [is_last[q] if c.kind.endswith("last") else ctr[q] == 0
                                    for q in range(lv, upto)]
                            m.d.comb += [now.eq(Cat(*want).all()), out.eq(lvl)]
            flag_out.append(out)

        chains: dict = {}

        def at(sig, offset):
            return delay_tap(m, chains, sig, offset)

        # ---- units, read ports and their delay lines -----------------------------------
        used = {s.resource[op.dst] for s, n in zip(scheds, nests, strict=True)
                for op in n.ops if op.kind != "neg"}
        cores: dict = {}
        outputs: dict = {}
        for lane in range(sch.lanes):
            for kind, cls in (("mul", Fp32Mul), ("add", Fp32Add)):
                cores[((kind,), lane)] = cls()
        for kind, cls in (("div", Fp32DivIter), ("sqrt", Fp32SqrtIter), ("cmp", Fp32Compare)):
            if ((kind,), 0) in used:
                cores[((kind,), 0)] = cls()
        for (res, inst), core in cores.items():
            m.submodules[f"{res[0]}{inst}"] = core
            m.d.comb += core.o.ready.eq(1)
            if res[0] in ("mul", "add", "cmp"):
                m.d.comb += core.i.valid.eq(1)
            if res[0] == "cmp":
                outputs[(res, inst)] = Cat(core.o.payload.lt, core.o.payload.equal)
            else:
                outputs[(res, inst)] = core.o.payload.r
        read_ports: dict = {}
        for name in self.arrays:
            n_ports = 1 + max([inst for (res, inst) in used if res == ("read", name)] + [0])
            for inst in range(n_ports):
                rp = self.memories[name].read_port(transparent_for=())
                read_ports[(("read", name), inst)] = rp
                outputs[(("read", name), inst)] = rp.data
        hist: dict = {key: [sig] for key, sig in outputs.items()}

        def tap(key, d):
            h = hist[key]
            while len(h) <= d:
                r = Signal.like(h[-1], name=f"h_{key[0][0]}{key[1]}_{len(h)}")
                m.d.sync += r.eq(h[-1])
                h.append(r)
            return h[d]

        values: dict = {}

        def val(key):
            if key in values:
                return values[key]
            kind = key[0]
            if kind == "const":
                v = Const(key[1], 32)
            elif kind == "tap":
                v = tap(key[1], key[2])
            elif kind == "cmp":
                h = tap(key[1], key[2])
                # 32 bits wide: a sign flip of a comparison's result reads bit 31
                v = Mux(h[0] | (h[1] & key[3]), Const(ONE, 32), Const(0, 32))
            elif kind == "neg":
                v = _neg(m, val(key[1]))
            elif kind == "acc":
                v = Mux(val(key[1]), val(key[2]), val(key[3]))
            elif kind == "flag":
                v = at(flag_out[key[1]], key[2])
            elif kind == "addr":
                v = at(addr_out[key[1]], key[2])
            elif kind == "iv":
                v = iv[key[1]]
            elif kind == "en":
                v = iv[key[1]] if key[2] is None else iv[key[1]] & val(key[2])
            else:  # "one"
                v = Const(1, 1)
            values[key] = v
            return v

        # ---- the control store -----------------------------------------------------------
        fields: dict = {}  # control point -> {source key: index}; index 0: nothing
        rows: list = []  # per (segment, phase): {control point: index}

        def addr_src(si, ad, t):
            """A fixed address is a constant of the control store (no generator, no delay
            line); the others are their slot's generator, delayed to ``t``."""
            return ("const", ad.offset) if _fixed(ad) else ("addr", addr_slot[si][ad], t)

        for si, (s, n) in enumerate(zip(scheds, nests, strict=True)):
            accs = n.acc_names()
            by_dst = {op.dst: op for op in n.ops}
            seg_rows = [{} for _ in range(s.ii)]
            rows.append(seg_rows)

            def put(t, point, key, seg_rows=seg_rows):
                f = fields.setdefault(point, {None: 0})
                idx = f.setdefault(key, len(f))
                row = seg_rows[t % len(seg_rows)]
                assert row.get(point, idx) == idx, (point, t)
                row[point] = idx

            def opnd(src, t, s=s, accs=accs, by_dst=by_dst, si=si):
                if src.startswith("c:"):
                    return ("const", int(src[2:], 16))
                if src in accs:
                    a = accs[src]
                    return ("acc", ("flag", flag_slot[si][a.reset], t), opnd(a.init, t),
                            opnd(a.update, t + a.distance * s.ii))
                op = by_dst[src]
                if op.kind == "neg":
                    return ("neg", opnd(op.srcs[0], t))
                d = t - s.ready[src]
                assert d >= 0, (src, t)
                if op.kind == "load":  # the read port's word is valid 1 cycle after issue
                    d += s.units.load_latency - 1
                if op.kind in ("lt", "le"):
                    return ("cmp", s.resource[src], d, int(op.kind == "le"))
                return ("tap", s.resource[src], d)

            for op in n.ops:
                if op.kind == "neg":
                    continue
                t = s.time[op.dst]
                key = s.resource[op.dst]
                if op.kind == "load":
                    put(t, ("raddr", key), addr_src(si, op.addr, t))
                    continue
                put(t, ("a", key), opnd(op.srcs[0], t))
                if len(op.srcs) > 1:
                    put(t, ("b", key), opnd(op.srcs[1], t))
                if op.kind == "sub":
                    put(t, ("sub", key), ("one",))
                if op.kind in ("div", "sqrt"):
                    put(t, ("go", key), ("iv", t))
            for k, st in enumerate(n.stores):
                t = s.time[("store", k)]
                flag = None if st.when is None else ("flag", flag_slot[si][st.when], t)
                put(t, ("wen", st.array), ("en", t, flag))
                put(t, ("waddr", st.array), addr_src(si, st.addr, t))
                put(t, ("wdata", st.array), opnd(st.src, t))

        points = list(fields)
        # every source is built here, outside the control switches (a delay line assigned
        # inside a Case would only shift while its case is selected)
        for f in fields.values():
            for key in f:
                if key is not None:
                    val(key)
        widths = [_bits(len(fields[p])) for p in points]
        words = []
        for seg_rows in rows:
            for row in seg_rows:
                w, sh = 0, 0
                for p, wd in zip(points, widths, strict=True):
                    w |= row.get(p, 0) << sh
                    sh += wd
                words.append(w)
        self.control_bits = sum(widths)
        self.control_rows = len(words)
        rom = Memory(shape=unsigned(max(1, sum(widths))), depth=len(words), init=words)
        m.submodules.control = rom
        crp = rom.read_port(domain="comb")
        m.d.comb += crp.addr.eq(rom_base + phase)
        sel = {}
        sh = 0
        for p, wd in zip(points, widths, strict=True):
            sel[p] = crp.data[sh:sh + wd]
            sh += wd

        def drive(point, target):
            if point not in fields:
                return
            with m.Switch(sel[point]):
                for key, idx in fields[point].items():
                    if key is not None:
                        with m.Case(idx):
                            m.d.comb += target.eq(val(key))

        for key, core in cores.items():
            p = core.i.payload
            inputs = [("a", p.a)]
            if key[0][0] != "sqrt":
                inputs.append(("b", p.b))
            if key[0][0] == "add":
                inputs.append(("sub", p.sub))
            if key[0][0] in ("div", "sqrt"):
                inputs.append(("go", core.i.valid))
            for point, target in inputs:
                if sch.units.operand_stage:  # the operand register stage
                    mux = Signal(len(target), name=f"{point}_{key[0][0]}{key[1]}")
                    drive((point, key), mux)
                    m.d.sync += target.eq(mux)
                else:
                    drive((point, key), target)

        # the host port: while idle, read port 0 and the write port of every array
        ab = self.array_bits
        host_sel = Signal.like(self.host_addr[ab:], name="host_sel")
        m.d.sync += host_sel.eq(self.host_addr[ab:])
        # host words are flushed on the way in (a subnormal -> the zero of its sign), as
        # run_sequence reads its memories
        host_flushed = Signal(32)
        hw = self.host_wdata
        m.d.comb += host_flushed.eq(Mux(hw[23:31] == 0, Cat(Const(0, 31), hw[31]), hw))
        for k, name in enumerate(self.arrays):
            for key, rp in read_ports.items():
                if key[0] == ("read", name):
                    with m.If(running):
                        drive(("raddr", key), rp.addr)
                    if key[1] == 0:
                        with m.If(~running):
                            m.d.comb += rp.addr.eq(self.host_addr[:ab])
            with m.If(host_sel == k):
                m.d.comb += self.host_rdata.eq(read_ports[(("read", name), 0)].data)
            wp = self.memories[name].write_port()
            with m.If(running):
                drive(("wen", name), wp.en)
                drive(("waddr", name), wp.addr)
                drive(("wdata", name), wp.data)
            with m.Else():
                m.d.comb += [wp.en.eq(self.host_we & (self.host_addr[ab:] == k)),
                             wp.addr.eq(self.host_addr[:ab]), wp.data.eq(host_flushed)]

        # ---- segment loading (last: it overrides the counters' updates) -----------------
        with m.If(load):
            m.d.sync += [running.eq(1), pos.eq(next_pos), left.eq(n_iter), phase.eq(0),
                         nidx.eq(0)]
            m.d.sync += [c.eq(0) for c in ctr]
            m.d.sync += [v.eq(0) for v in iv[1:]]
        return m


def simulate_sequence(schedule: SequenceSchedule, memories: dict, entries: list,
                      init: dict | None = None):
    """Run the sequence machine in Amaranth's simulator
    (:func:`navgate.opflow.loopmachine.simulate_entries`): one (array -> uint32 words,
    cycles from start to done) per entry run."""
    prog = schedule.program
    try:
        return simulate_entries(SequenceMachine(schedule, init), prog.arrays, memories,
                                entries, lambda e: 10 * schedule.cycles(e) + 100)
    except RuntimeError as e:
        raise RuntimeError(f"{prog.name}: {e}") from None
