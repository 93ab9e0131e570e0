"""The scheduled float32 datapath of seed 003's attitude circuit: shared units, register
banks and a control ROM generated from the schedule.

References: :mod:`navgate.systems.attitude.schedule` (the rules this hardware follows) and
seed 004's scheduled datapath (:mod:`navgate.systems.kf2x2.top`, control generated from the
schedule). One :class:`ScheduledDatapath` runs one program (the whole solve for
``attitude_top``, one module's part of it for the per-module blocks):

* units: :class:`~navgate.gateware.fp32.Fp32Mul`, :class:`~navgate.gateware.fp32.Fp32Add`,
  :class:`~navgate.gateware.fp32.Fp32Div` and :class:`~navgate.gateware.fp32.Fp32Sqrt` (both
  with two recurrence steps per stage, latencies 18 and 17),
  :class:`~navgate.systems.attitude.units.MiscUnit`,
  :class:`~navgate.systems.attitude.units.AtanUnit`; only the kinds the program uses are
  built. Their outputs are never stalled (``o.ready = 1``), so every latency is exact.
* operands: each unit port reads, through one multiplexer, a register bank (distributed RAM,
  one write port, asynchronous read), a flip-flop register of the parent (``src_*``:
  inputs, state, parameters, constants) or a unit output in the cycle it appears (bypass);
* results: written into a bank (address from the register allocation) or, for sinks,
  handed to the parent (``we_<reg>`` / ``wd_<reg>``) to be stored in its flip-flops;
* control: a ROM of one word per program cycle (issue bits, add/sub, misc opcode, operand
  selects and bank addresses, bank write enables/addresses/sources, sink write enables),
  read two cycles ahead into a register. ``start`` (one cycle) begins program cycle 0 in the
  next cycle; ``last`` is high in the final program cycle, at whose end the last results
  are written.
"""

from __future__ import annotations

from amaranth.hdl import Module, Signal, unsigned
from amaranth.lib import data, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware.fp32 import Fp32Add, Fp32Div, Fp32Mul, Fp32Sqrt
from navgate.systems.attitude.program import CONSTANTS
from navgate.systems.attitude.schedule import (
    LATENCY,
    PORTS,
    Schedule,
    build_schedule,
)
from navgate.systems.attitude.units import MISC_OPS, AtanUnit, MiscUnit

__all__ = ["ScheduledDatapath", "STEPS_PER_STAGE", "unit_latencies", "make_schedule"]

STEPS_PER_STAGE = 2  #: recurrence steps per pipeline stage of the divider and square root


def _make_unit(kind: str):
    if kind == "mul":
        return Fp32Mul()
    if kind == "add":
        return Fp32Add()
    if kind == "div":
        return Fp32Div(steps_per_stage=STEPS_PER_STAGE)
    if kind == "sqrt":
        return Fp32Sqrt(steps_per_stage=STEPS_PER_STAGE)
    if kind == "misc":
        return MiscUnit()
    if kind == "atan":
        return AtanUnit()
    raise ValueError(kind)


def unit_latencies() -> dict:
    """Latency of every unit kind as :func:`_make_unit` builds it (the schedule is made with
    these), read from the classes without building a unit."""
    fixed = {"mul": Fp32Mul, "add": Fp32Add, "misc": MiscUnit, "atan": AtanUnit}
    stepped = {"div": Fp32Div, "sqrt": Fp32Sqrt}
    out = {}
    for k in PORTS:
        if k in stepped:
            out[k] = stepped[k].latency_for(STEPS_PER_STAGE)
        else:
            out[k] = fixed[k].LATENCY
    return out


def make_schedule(program, sources, sinks, **kw) -> Schedule:
    lat = unit_latencies()
    lat["atan"] = AtanUnit.LATENCY
    assert lat["misc"] == LATENCY["misc"]
    return build_schedule(program, sources, sinks, latency=lat, **kw)


def _bits(n: int) -> int:
    return max(1, (n - 1).bit_length())


class ScheduledDatapath(wiring.Component):
    """One program on shared units (see the module docstring). Ports: ``start`` (in),
    ``busy``, ``last``, ``phase`` (index into ``schedule.phases`` of the running program
    cycle), ``atan_sat`` (an arctangent result leaving its unit had a saturated input);
    ``src_<name>`` (32-bit inputs) for every non-constant source; ``we_<reg>`` and
    ``wd_<reg>`` for every sink register."""

    def __init__(self, schedule: Schedule):
        self.schedule = s = schedule
        self.kinds = sorted({p.op.unit for p in s.ops}, key=list(PORTS).index)
        self.src_names = [n for n in s.sources if n not in CONSTANTS]
        for lst in s.port_sources.values():  # sink registers read back after their write
            for src in lst:
                if src[0] == "ff" and src[1] not in CONSTANTS and src[1] not in self.src_names:
                    self.src_names.append(src[1])
        self.sink_regs = sorted(set(s.sinks.values()), key=list(s.sinks.values()).index)
        sig = {"start": In(1), "busy": Out(1), "last": Out(1),
               "phase": Out(range(max(2, len(s.phases)))), "atan_sat": Out(1)}
        for n in self.src_names:
            sig[f"src_{n}"] = In(32)
        for r in self.sink_regs:
            sig[f"we_{r}"] = Out(1)
            sig[f"wd_{r}"] = Out(32)
        super().__init__(sig)
        self.LATENCY = s.length  #: program cycles from the cycle after ``start``
        self.THROUGHPUT = 1 / (s.length + 1)
        self._build_words()

    # ------------------------------------------------------------------ microcode
    def _build_words(self):
        s = self.schedule
        banks = len(s.bank_depth)
        self.bank_users = {k: [] for k in range(banks)}  # units writing bank k
        for p in s.ops:
            if p.dest[0] == "bank" and p.op.unit not in self.bank_users[p.dest[1]]:
                self.bank_users[p.dest[1]].append(p.op.unit)
        fields = {}
        for u in self.kinds:
            fields[f"iss_{u}"] = 1
        fields["sub"] = 1
        fields["mop"] = 2
        self.ports = [(u, pt) for u in self.kinds for pt in PORTS[u]
                      if (u, pt) in s.port_sources]
        self.addr_bits = _bits(max(max(s.bank_depth, default=1), 2))
        for u, pt in self.ports:
            fields[f"sel_{u}_{pt}"] = _bits(len(s.port_sources[(u, pt)]))
            fields[f"adr_{u}_{pt}"] = self.addr_bits
        for k in range(banks):
            fields[f"bwe_{k}"] = 1
            fields[f"bwa_{k}"] = self.addr_bits
            fields[f"bws_{k}"] = _bits(len(self.bank_users[k]) or 1)
        for r in self.sink_regs:
            fields[f"swe_{r}"] = 1
        self.layout = data.StructLayout(fields)
        words = [dict() for _ in range(s.length)]
        for p in s.ops:
            u = p.op.unit
            w = words[p.cycle]
            w[f"iss_{u}"] = 1
            if p.op.kind == "sub":
                w["sub"] = 1
            if u == "misc":
                w["mop"] = MISC_OPS[p.op.kind]
            for pt, a in zip(PORTS[u], p.op.args, strict=False):
                src = s.read_source(a, p.cycle)
                key = src[:2] if src[0] == "bank" else src
                w[f"sel_{u}_{pt}"] = s.port_sources[(u, pt)].index(key)
                if src[0] == "bank":
                    w[f"adr_{u}_{pt}"] = src[2]
            d = words[p.done]
            if p.dest[0] == "bank":
                k = p.dest[1]
                d[f"bwe_{k}"] = 1
                d[f"bwa_{k}"] = p.dest[2]
                d[f"bws_{k}"] = self.bank_users[k].index(u)
            else:
                d[f"swe_{p.dest[1]}"] = 1
        self.sink_unit = {s.sinks[p.op.name]: p.op.unit for p in s.ops if p.dest[0] == "ff"}
        offs = {}
        off = 0
        for name, width in fields.items():
            offs[name] = (off, width)
            off += width
        self.word_bits = off
        self.words = []
        for w in words:
            v = 0
            for name, val in w.items():
                o, width = offs[name]
                assert 0 <= val < (1 << width), (name, val)
                v |= val << o
            self.words.append(v)

    # ------------------------------------------------------------------ hardware
    def elaborate(self, platform):
        m = Module()
        s = self.schedule
        n = s.length
        rom = Memory(shape=unsigned(self.word_bits), depth=n, init=self.words)
        m.submodules.rom = rom
        # synchronous read plus an output register: the word of cycle k is addressed in
        # cycle k - 2 (the register keeps the block RAM's slow clock-to-output off the
        # operand paths). Idle (and the last two program cycles) address word 0, so that
        # word 0 is in the register when the program starts.
        rd = rom.read_port()
        word = Signal(self.word_bits)
        m.d.sync += word.eq(rd.data)
        cyc = Signal(range(n + 2))
        go = self.start & ~self.busy
        with m.If(go):
            m.d.sync += [self.busy.eq(1), cyc.eq(0)]
        with m.Elif(self.busy):
            m.d.sync += cyc.eq(cyc + 1)
            with m.If(cyc == n - 1):
                m.d.sync += self.busy.eq(0)
        m.d.comb += [rd.en.eq(1), self.last.eq(self.busy & (cyc == n - 1))]
        with m.If(go & (n > 1)):
            m.d.comb += rd.addr.eq(1)
        with m.Elif(self.busy & (cyc + 2 < n)):
            m.d.comb += rd.addr.eq(cyc + 2)
        w = data.View(self.layout, word)
        act = self.busy

        # FSM state (phase) from the cycle counter
        for i, (lo, _hi) in enumerate(s.phase_windows):
            with m.If(self.busy & (cyc >= lo)):
                m.d.comb += self.phase.eq(i)

        units = {}
        for u in self.kinds:
            units[u] = _make_unit(u)
            m.submodules[f"u_{u}"] = units[u]
            m.d.comb += [units[u].o.ready.eq(1),
                         units[u].i.valid.eq(act & getattr(w, f"iss_{u}"))]
        outs = {u: (units[u].o.payload.r) for u in self.kinds}

        # register banks
        banks = []
        for k, depth in enumerate(s.bank_depth):
            # distributed RAM (Yosys maps a small many-port memory to flip-flops and
            # multiplexers otherwise, which costs about three times the LUTs)
            mem = Memory(shape=unsigned(32), depth=max(depth, 2), init=[],
                         attrs={"ram_style": "distributed"})
            m.submodules[f"bank{k}"] = mem
            wp = mem.write_port()
            users = self.bank_users[k]
            m.d.comb += [wp.en.eq(act & getattr(w, f"bwe_{k}")),
                         wp.addr.eq(getattr(w, f"bwa_{k}"))]
            with m.Switch(getattr(w, f"bws_{k}")):
                for j, u in enumerate(users):
                    with m.Case(j):
                        m.d.comb += wp.data.eq(outs[u])
            banks.append(mem)

        # operand multiplexers
        srcs = {n_: getattr(self, f"src_{n_}") for n_ in self.src_names}
        for u, pt in self.ports:
            lst = s.port_sources[(u, pt)]
            val = Signal(32, name=f"op_{u}_{pt}")
            addr = getattr(w, f"adr_{u}_{pt}")
            with m.Switch(getattr(w, f"sel_{u}_{pt}")):
                for j, src in enumerate(lst):
                    with m.Case(j):
                        if src[0] == "bank":
                            rp = banks[src[1]].read_port(domain="comb")
                            m.d.comb += [rp.addr.eq(addr), val.eq(rp.data)]
                        elif src[0] == "unit":
                            m.d.comb += val.eq(outs[src[1]])
                        elif src[1] in CONSTANTS:
                            m.d.comb += val.eq(CONSTANTS[src[1]])
                        else:
                            m.d.comb += val.eq(srcs[src[1]])
            m.d.comb += getattr(units[u].i.payload, pt).eq(val)
        if "add" in units:
            m.d.comb += units["add"].i.payload.sub.eq(w.sub)
        if "misc" in units:
            m.d.comb += units["misc"].i.payload.op.eq(w.mop)
        if "atan" in units:
            m.d.comb += self.atan_sat.eq(units["atan"].o.valid
                                         & units["atan"].o.payload.saturated)

        # sink writes
        for r in self.sink_regs:
            m.d.comb += [getattr(self, f"we_{r}").eq(act & getattr(w, f"swe_{r}")),
                         getattr(self, f"wd_{r}").eq(outs[self.sink_unit[r]])]
        return m
