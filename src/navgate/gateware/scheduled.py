"""The op form shared by navgate's scheduled float32 datapaths, and the command-stream
wrapper of their machines.

Programs
--------
A program is a list of ops with ``dst``, ``kind`` and ``srcs`` (SSA: every ``dst`` is a new
temporary), a ``commit`` map (register <- temporary, all reads of a register in the program
see its value at program start) and ``outputs`` (name -> temporary) -- the form of
:class:`navgate.systems.ins_trn.pl.fp32_program.Program`. Kinds: ``add sub mul div sqrt le lt
cvt neg``; ``neg`` is a sign flip folded into its consumers' operand paths
(:func:`_fold_negs`; it must feed arithmetic ops only). Register names that are not
temporaries are persistent: ``c:<hex>`` constants (initial contents) and the names the
machine's image lists. Cores: ``mul`` (Fp32Mul, 5), ``add`` (Fp32Add, add/sub, 8), ``div``,
``sqrt``, ``cmp`` (Fp32Compare, 2, result 1.0/0.0), ``cvt`` (Fp32FromInt(32): a register
holding a two's complement integer, 4) and ``mov`` (a one-cycle copy for commits that cannot
be written in place).

The scheduler, register allocation, microcode and machine are in
:mod:`navgate.gateware.banked` (register banks with one write port each, the form that maps
onto block RAM); an earlier machine with one multi-ported register file was removed when it
measured 151,653 LUT for seed 000's mechanization (docs/seed000-engines.md).
:class:`ScheduledMachineStream` puts a machine behind one ``lib.stream`` command stream.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from amaranth.hdl import Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.fp32 import Fp32Add, Fp32Compare, Fp32Div, Fp32Mul, Fp32Sqrt

__all__ = ["UNIT_OF_KIND", "UNIT_LATENCY", "SOp", "ScheduledProgram", "ScheduleError",
           "ONE_BITS", "QNAN_BITS", "ScheduledMachineStream", "CMD_WRITE", "CMD_READ", "CMD_START"]

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


class _Mov(wiring.Component):
    """One-cycle register (the commit copy)."""

    LATENCY = 1

    def __init__(self):
        super().__init__({"a": In(32), "valid_i": In(1), "r": Out(32), "valid_o": Out(1)})

    def elaborate(self, platform):
        m = Module()
        m.d.sync += [self.r.eq(self.a), self.valid_o.eq(self.valid_i)]
        return m


CMD_WRITE, CMD_READ, CMD_START = 0, 1, 2


class ScheduledMachineStream(wiring.Component):
    """The machine of ``image`` (the banked machine of
    :mod:`navgate.gateware.banked`) behind one command stream (for the verification harness and
    the ``rtl`` engine). Input payload ``{cmd, addr, data, prog}``: ``cmd`` 0 writes ``data``
    to register ``addr``, 1 reads register ``addr``, 2 runs program ``prog``. One output
    ``{data, cycles}`` per command: the word read (0 otherwise) and, for a run, the cycles
    from start to done (``cycles(prog) + 1``). A write or read takes 2 cycles + the
    handshake, a run ``cycles + 2``."""

    LATENCY = 3
    THROUGHPUT = 0.5

    def __init__(self, image, init: dict | None = None):
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
