"""A small float32 sequencer: runs a straight-line program of float32 operations on one shared
adder, one multiplier and one int->float converter (the ``navgate.gateware.fp32`` cores).

Seed 000's ``imu_calibration`` and the BMP390 ``compensation_engine`` are both short programs
run once per sample (400 Hz and 25 Hz), so one set of float32 units executing one operation
at a time is far below the time budget (docs/sensors-gateware.md) and costs the least logic.

The program is a tuple of ``(op, dst, src_a[, src_b])`` with ops ``i2f`` (int32 -> float32,
:func:`navgate.numerics.fp32.fp32_from_int`), ``add``, ``sub``, ``mul`` and register *names*;
the bit-true model is the same program interpreted with :mod:`navgate.numerics.fp32`
(:func:`navgate.devices.bmp390.run_fp32_program`), so the gateware matches it bit for bit by
construction of the order of operations (and the tests check it).

Register file: one LUT RAM of 32-bit words, with the inputs first, then the parameters
(writable through ``par_*`` while the engine is idle), then constants (initial values) and
temporaries. Per sample: load the inputs (one per cycle), run, unload the outputs (one per
cycle). An operation takes one issue cycle plus the unit's latency (the result is written back
in the cycle it appears).
"""

from __future__ import annotations

from fractions import Fraction

from amaranth.hdl import Const, Module, Signal, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware.fp32 import Fp32Add, Fp32FromInt, Fp32Mul
from navgate.systems.ins_trn.pl.shared_units import unit_members, unit_port

OPS = {"i2f": 0, "add": 1, "sub": 2, "mul": 3}


class Program:
    """Register allocation of a named straight-line program."""

    def __init__(self, program, inputs, outputs, params=(), consts=None, param_init=None):
        from navgate.numerics.fp32 import f32_to_bits

        self.program = tuple(program)
        self.inputs, self.outputs, self.params = tuple(inputs), tuple(outputs), tuple(params)
        consts = dict(consts or {})
        names = list(self.inputs) + list(self.params) + list(consts)
        for op, dst, *src in self.program:
            if op not in OPS:
                raise ValueError(f"unknown op {op!r}")
            for s in src:
                if s not in names:
                    raise ValueError(f"register {s!r} read before it is written")
            if dst not in names:
                names.append(dst)
        for o in self.outputs:
            if o not in names:
                raise ValueError(f"output {o!r} is never written")
        self.index = {n: i for i, n in enumerate(names)}
        self.depth = len(names)
        init = [0] * self.depth
        for k, v in consts.items():
            init[self.index[k]] = int(f32_to_bits(float(v)))
        for k, v in (param_init or {}).items():
            init[self.index[k]] = int(v) & 0xFFFFFFFF
        self.init = init
        self.addr_bits = max(1, (self.depth - 1).bit_length())

    def _op_cycles(self) -> int:
        lat = {"i2f": Fp32FromInt.LATENCY, "add": Fp32Add.LATENCY, "sub": Fp32Add.LATENCY,
               "mul": Fp32Mul.LATENCY}
        return sum(lat[op] + 1 for op, *_ in self.program)  # issue, then write-back at valid

    @property
    def latency(self) -> int:
        """Cycles from the input accepted (end of the load) to ``o.valid``."""
        return self._op_cycles() + len(self.outputs) + 1

    @property
    def cycles(self) -> int:
        """Cycles per run, back to back: load + operations + unload + handshakes."""
        return len(self.inputs) + self._op_cycles() + len(self.outputs) + 2


class Fp32Sequencer(wiring.Component):
    """Runs :class:`Program` once per input: stream ``i`` {inputs} -> stream ``o`` {outputs}.

    ``par_we``/``par_addr``/``par_data`` write parameter ``par_addr`` (index into
    ``program.params``) when ``par_ready`` (engine idle). All words are 32-bit (float32 bit
    patterns, or two's complement integers for ``i2f`` sources).
    """

    def __init__(self, program: Program, shared_units: bool = False):
        self.prog = program
        #: True: the adder, multiplier and converter are outside (ports ``add_i/add_o`` ... of
        #: :mod:`navgate.systems.ins_trn.pl.shared_units`); ``busy`` is high from the cycle
        #: after an input is taken until the output has been taken
        self.shared_units = shared_units
        self.LATENCY = program.latency
        self.THROUGHPUT = Fraction(1, program.cycles)
        pbits = max(1, (max(1, len(program.params)) - 1).bit_length())
        super().__init__({
            "i": In(stream.Signature(data.StructLayout(
                {n: unsigned(32) for n in program.inputs}))),
            "o": Out(stream.Signature(data.StructLayout(
                {n: unsigned(32) for n in program.outputs}))),
            "par_we": In(1), "par_addr": In(pbits), "par_data": In(32), "par_ready": Out(1),
            "busy": Out(1),
            **(unit_members() if shared_units else {}),
        })

    def elaborate(self, platform):
        m = Module()
        p = self.prog
        ab = p.addr_bits
        if self.shared_units:
            add, mul, cvt = (unit_port(self, u) for u in ("add", "mul", "cvt"))
        else:
            m.submodules.add = add = Fp32Add()
            m.submodules.mul = mul = Fp32Mul()
            m.submodules.cvt = cvt = Fp32FromInt(32)
        m.submodules.rf = rf = Memory(shape=unsigned(32), depth=p.depth, init=p.init)
        ra = rf.read_port(domain="comb")
        rb = rf.read_port(domain="comb")
        wp = rf.write_port()

        # program ROM: op | dst | a | b
        words = []
        for op, dst, *src in p.program:
            a = p.index[src[0]]
            b = p.index[src[1]] if len(src) > 1 else 0
            words.append(OPS[op] | (p.index[dst] << 2) | (a << (2 + ab)) | (b << (2 + 2 * ab)))
        m.submodules.rom = rom = Memory(shape=unsigned(2 + 3 * ab), depth=len(words),
                                        init=words)
        rr = rom.read_port(domain="comb")
        pc = Signal(range(len(words) + 1))
        m.d.comb += rr.addr.eq(pc)
        op = rr.data[0:2]
        dst = rr.data[2:2 + ab]
        m.d.comb += [ra.addr.eq(rr.data[2 + ab:2 + 2 * ab]),
                     rb.addr.eq(rr.data[2 + 2 * ab:2 + 3 * ab])]
        m.d.comb += [add.o.ready.eq(1), mul.o.ready.eq(1), cvt.o.ready.eq(1),
                     add.i.payload.a.eq(ra.data), add.i.payload.b.eq(rb.data),
                     add.i.payload.sub.eq(op == OPS["sub"]),
                     mul.i.payload.a.eq(ra.data), mul.i.payload.b.eq(rb.data),
                     cvt.i.payload.x.eq(ra.data)]

        n_in, n_out = len(p.inputs), len(p.outputs)
        k = Signal(range(max(n_in, n_out) + 1))
        in_words = [getattr(self.i.payload, n) for n in p.inputs]
        out_regs = [Signal(32, name=f"out_{n}") for n in p.outputs]
        m.d.comb += [getattr(self.o.payload, n).eq(r) for n, r in zip(p.outputs, out_regs,
                                                                         strict=True)]
        last_pc = len(words) - 1
        m.d.comb += self.busy.eq(~self.par_ready)  # par_ready: the IDLE state
        with m.FSM():
            with m.State("IDLE"):
                m.d.comb += self.par_ready.eq(1)
                with m.If(self.par_we):
                    m.d.comb += [wp.en.eq(1), wp.addr.eq(n_in + self.par_addr),
                                 wp.data.eq(self.par_data)]
                with m.Elif(self.i.valid):
                    m.d.sync += k.eq(0)
                    m.next = "LOAD"
            with m.State("LOAD"):
                m.d.comb += [wp.en.eq(1), wp.addr.eq(k)]
                with m.Switch(k):
                    for j, w in enumerate(in_words):
                        with m.Case(j):
                            m.d.comb += wp.data.eq(w)
                m.d.sync += k.eq(k + 1)
                with m.If(k == n_in - 1):
                    m.d.comb += self.i.ready.eq(1)
                    m.d.sync += pc.eq(0)
                    m.next = "ISSUE"
            with m.State("ISSUE"):
                with m.Switch(op):
                    with m.Case(OPS["i2f"]):
                        m.d.comb += cvt.i.valid.eq(1)
                    with m.Case(OPS["add"], OPS["sub"]):
                        m.d.comb += add.i.valid.eq(1)
                    with m.Case(OPS["mul"]):
                        m.d.comb += mul.i.valid.eq(1)
                m.next = "WAIT"  # the units are always ready when idle
            with m.State("WAIT"):
                result = Signal(32)
                got = Signal()
                with m.Switch(op):
                    with m.Case(OPS["i2f"]):
                        m.d.comb += [got.eq(cvt.o.valid), result.eq(cvt.o.payload.r)]
                    with m.Case(OPS["add"], OPS["sub"]):
                        m.d.comb += [got.eq(add.o.valid), result.eq(add.o.payload.r)]
                    with m.Case(OPS["mul"]):
                        m.d.comb += [got.eq(mul.o.valid), result.eq(mul.o.payload.r)]
                with m.If(got):
                    m.d.comb += [wp.en.eq(1), wp.addr.eq(dst), wp.data.eq(result)]
                    m.d.sync += pc.eq(pc + 1)
                    with m.If(pc == last_pc):
                        m.d.sync += k.eq(0)
                        m.next = "UNLOAD"
                    with m.Else():
                        m.next = "ISSUE"
            with m.State("UNLOAD"):
                with m.Switch(k):
                    for j, name in enumerate(p.outputs):
                        with m.Case(j):
                            m.d.comb += ra.addr.eq(Const(p.index[name], ab))
                            m.d.sync += out_regs[j].eq(ra.data)
                m.d.sync += k.eq(k + 1)
                with m.If(k == n_out - 1):
                    m.next = "OUT"
            with m.State("OUT"):
                m.d.comb += self.o.valid.eq(1)
                with m.If(self.o.ready):
                    m.next = "IDLE"
        return m
