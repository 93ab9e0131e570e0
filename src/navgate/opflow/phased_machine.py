"""The phased datapath of opflow: shared units, register banks and a control ROM generated
from a :mod:`navgate.opflow.phased` schedule (the rules this hardware follows).

One :class:`PhasedDatapath` runs one program:

* units: one per unit kind the schedule uses, built by the client's ``make_unit(kind)``
  (stream components with payload ``i`` = the operand ports, ``o`` = ``r``); their outputs
  are never stalled (``o.ready = 1``), so every latency is exact.
* operands: each unit port reads, through one multiplexer, a register bank (distributed RAM,
  one write port, asynchronous read), a flip-flop register of the parent (``src_*``:
  inputs, state, parameters), a constant or a unit output in the cycle it appears (bypass);
* results: written into a bank (address from the register allocation) or, for sinks,
  handed to the parent (``we_<reg>`` / ``wd_<reg>``) to be stored in its flip-flops;
* control: a ROM of one word per program cycle (issue bits, the client's op-select fields
  (:class:`Control`), operand selects and bank addresses, bank write enables/addresses/
  sources, sink write enables), read two cycles ahead into a register. ``start`` (one
  cycle, at least two cycles after reset: the word of cycle 0 is read while idle) begins
  program cycle 0 in the next cycle; ``last`` is high in the final program cycle, at whose
  end the last results are written.
* flags: one-bit outputs raised by a unit's result (``flags``: port -> (unit, payload
  field), sampled while the unit's output is valid).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from amaranth.hdl import Module, Signal, unsigned
from amaranth.lib import data, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.opflow.phased import Schedule

__all__ = ["Control", "PhasedDatapath"]


@dataclass(frozen=True)
class Control:
    """A control-word field that tells a unit which op it runs: ``codes[kind]`` drives the
    unit's input payload field ``payload`` (kinds not listed leave the field 0)."""

    field: str
    width: int
    unit: str
    payload: str
    codes: dict


def _bits(n: int) -> int:
    return max(1, (n - 1).bit_length())


class PhasedDatapath(wiring.Component):
    """One program on shared units (see the module docstring). Ports: ``start`` (in),
    ``busy``, ``last``, ``phase`` (index into ``schedule.phases`` of the running program
    cycle), one per flag; ``src_<name>`` (32-bit inputs) for every non-constant source;
    ``we_<reg>`` and ``wd_<reg>`` for every sink register."""

    def __init__(self, schedule: Schedule, make_unit: Callable, controls: tuple = (),
                 flags: dict | None = None):
        self.schedule = s = schedule
        self.make_unit = make_unit
        self.controls = tuple(controls)
        self.flags = dict(flags or {})
        order = list(s.units.ports)
        self.kinds = sorted({p.unit for p in s.ops}, key=order.index)
        consts = s.constants
        self.src_names = [n for n in s.sources if n not in consts]
        for lst in s.port_sources.values():  # sink registers read back after their write
            for src in lst:
                if src[0] == "ff" and src[1] not in consts and src[1] not in self.src_names:
                    self.src_names.append(src[1])
        self.sink_regs = sorted(set(s.sinks.values()), key=list(s.sinks.values()).index)
        sig = {"start": In(1), "busy": Out(1), "last": Out(1),
               "phase": Out(range(max(2, len(s.phases))))}
        for name in self.flags:
            sig[name] = Out(1)
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
        ports_of = s.units.ports
        banks = len(s.bank_depth)
        self.bank_users = {k: [] for k in range(banks)}  # units writing bank k
        for p in s.ops:
            if p.dest[0] == "bank" and p.unit not in self.bank_users[p.dest[1]]:
                self.bank_users[p.dest[1]].append(p.unit)
        fields = {}
        for u in self.kinds:
            fields[f"iss_{u}"] = 1
        for c in self.controls:
            fields[c.field] = c.width
        self.ports = [(u, pt) for u in self.kinds for pt in ports_of[u]
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
            u = p.unit
            w = words[p.cycle]
            w[f"iss_{u}"] = 1
            for c in self.controls:
                if c.unit == u and p.op.kind in c.codes:
                    w[c.field] = c.codes[p.op.kind]
            for pt, a in zip(ports_of[u], p.op.srcs, strict=False):
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
        self.sink_unit = {s.sinks[p.op.dst]: p.unit for p in s.ops if p.dest[0] == "ff"}
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
            units[u] = self.make_unit(u)
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
                        elif src[1] in s.constants:
                            m.d.comb += val.eq(s.constants[src[1]])
                        else:
                            m.d.comb += val.eq(srcs[src[1]])
            m.d.comb += getattr(units[u].i.payload, pt).eq(val)
        for c in self.controls:
            if c.unit in units:
                m.d.comb += getattr(units[c.unit].i.payload, c.payload).eq(getattr(w, c.field))
        for name, (u, fld) in self.flags.items():
            if u in units:
                m.d.comb += getattr(self, name).eq(units[u].o.valid
                                                   & getattr(units[u].o.payload, fld))

        # sink writes
        for r in self.sink_regs:
            m.d.comb += [getattr(self, f"we_{r}").eq(act & getattr(w, f"swe_{r}")),
                         getattr(self, f"wd_{r}").eq(outs[self.sink_unit[r]])]
        return m
