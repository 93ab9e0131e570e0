"""Seed 003's small units: the one-cycle ``misc`` unit and the fix16 arctangent.

References: seed 003 section 3.1.8 (反正切函数电路: ``in_a`` = cos, ``in_b`` = sin,
``out_result`` = radians; states 32to16, atan, 16to32, END) and the bit-true models
:func:`navgate.systems.attitude.atan16.atan_fp32` (arctangent) and
:mod:`navgate.systems.attitude.program` (``neg``, ``dbl``, ``clampneg``, ``yawsel``).

:class:`AtanUnit` (fixed latency, no back-pressure: ``o.ready`` is ignored)
    32to16: two :class:`~navgate.gateware.fp32.Fp32ToFixed` (Q2.13, 16 bits) side by side
    (6 cycles); atan: one iterative vectoring CORDIC with the seed's radian table
    (:data:`~navgate.systems.attitude.atan16.ATAN_TABLE`, 2 guard bits, +-pi/2 pre-rotation
    on load, 15 iterations, one per cycle); 16to32: truncation of the Q2.14 accumulator to
    Q2.13 and :class:`~navgate.gateware.fp32.Fp32FromFixed` (4 cycles).
    ``LATENCY = 26``, one input every ``II = 16`` cycles (``THROUGHPUT = 1/16``): an input may
    be offered 16 cycles after the previous one, the CORDIC being busy from cycle 7 to 21.
:class:`MiscUnit`
    ``op`` 0 ``neg``, 1 ``dbl`` (= ``fp32_add(a, a)``: exponent + 1, with the adder's
    flush, overflow and NaN rules), 2 ``clampneg`` (``a < 0`` -> +0), 3 ``yawsel``
    (``a < 0 ? b : a``); ``a < 0`` is ``fp32_compare(a, 0).lt``: a non-zero, non-NaN
    negative number (subnormals read as zero). ``LATENCY = 1``.
:class:`AtanCircuit`
    :class:`AtanUnit` behind the seed's port list (table 3-7) for ``navgate build``.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth.hdl import Array, C, Cat, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.fp32 import Fp32FromFixed, Fp32ToFixed
from navgate.gateware.fp32._common import QNAN
from navgate.systems.attitude.atan16 import (
    ATAN_TABLE,
    GUARD,
    HALF_PI_Z,
    IN_FRAC,
    ITERATIONS,
    OUT_FRAC,
    WIDTH,
    Z_FRAC,
)

__all__ = ["AtanUnit", "AtanCircuit", "MiscUnit", "MISC_OPS"]

MISC_OPS = {"neg": 0, "dbl": 1, "clampneg": 2, "yawsel": 3}
XY_BITS = WIDTH + GUARD + 4  #: |(x, y)| K < 2^(16+2) * sqrt(2) * 1.65 < 2^20.3, signed
Z_BITS = 18  #: |z| <= pi/2 + sum(table) < 3.32 rad = 54,400 LSB of Q2.14, signed


def _negative(x):
    """``fp32_compare(x, 0).lt``: sign set, exponent non-zero, not a NaN."""
    exp = x[23:31]
    nan = (exp == 0xFF) & (x[0:23] != 0)
    return x[31] & (exp != 0) & ~nan


class MiscUnit(wiring.Component):
    """The one-cycle bit-manipulation unit (``op``, ``a``, ``b`` -> ``r``)."""

    LATENCY = 1
    THROUGHPUT = 1

    def __init__(self):
        layout = data.StructLayout({"a": unsigned(32), "b": unsigned(32), "op": unsigned(2)})
        super().__init__({"i": In(stream.Signature(layout)),
                          "o": Out(stream.Signature(data.StructLayout({"r": unsigned(32)})))})

    def elaborate(self, platform):
        m = Module()
        a, b, op = self.i.payload.a, self.i.payload.b, self.i.payload.op
        sign, exp, frac = a[31], a[23:31], a[0:23]
        nan = (exp == 0xFF) & (frac != 0)
        r = Signal(32)
        with m.Switch(op):
            with m.Case(MISC_OPS["neg"]):
                with m.If(nan):
                    m.d.comb += r.eq(QNAN)
                with m.Elif(exp == 0):
                    m.d.comb += r.eq(Cat(C(0, 31), ~sign))
                with m.Else():
                    m.d.comb += r.eq(Cat(a[0:31], ~sign))
            with m.Case(MISC_OPS["dbl"]):
                with m.If(nan):
                    m.d.comb += r.eq(QNAN)
                with m.Elif(exp == 0):
                    m.d.comb += r.eq(Cat(C(0, 31), sign))
                with m.Elif(exp >= 0xFE):  # 2 * max-exponent overflows; inf stays inf
                    m.d.comb += r.eq(Cat(C(0, 23), C(0xFF, 8), sign))
                with m.Else():
                    m.d.comb += r.eq(Cat(frac, (exp + 1)[0:8], sign))
            with m.Case(MISC_OPS["clampneg"]):
                m.d.comb += r.eq(Mux(_negative(a), 0, a))
            with m.Case(MISC_OPS["yawsel"]):
                m.d.comb += r.eq(Mux(_negative(a), b, a))
        m.d.comb += self.i.ready.eq(1)
        m.d.sync += [self.o.valid.eq(self.i.valid), self.o.payload.r.eq(r)]
        return m


class AtanUnit(wiring.Component):
    """Seed 003's arctangent: ``{a: cos, b: sin}`` (float32) -> ``{r: radians (float32),
    saturated}``; fixed latency, one input per ``II`` cycles (see the module docstring)."""

    LATENCY = Fp32ToFixed.LATENCY + ITERATIONS + 1 + Fp32FromFixed.LATENCY
    II = ITERATIONS + 1
    THROUGHPUT = Fraction(1, ITERATIONS + 1)

    def __init__(self):
        li = data.StructLayout({"a": unsigned(32), "b": unsigned(32)})
        lo = data.StructLayout({"r": unsigned(32), "saturated": unsigned(1)})
        super().__init__({"i": In(stream.Signature(li)), "o": Out(stream.Signature(lo))})

    def elaborate(self, platform):
        m = Module()
        m.submodules.fx = fx = Fp32ToFixed(width=WIDTH, frac_bits=IN_FRAC)
        m.submodules.fy = fy = Fp32ToFixed(width=WIDTH, frac_bits=IN_FRAC)
        m.submodules.tof = tof = Fp32FromFixed(width=WIDTH, frac_bits=OUT_FRAC)
        m.d.comb += [
            fx.i.valid.eq(self.i.valid), fx.i.payload.a.eq(self.i.payload.a),
            fy.i.valid.eq(self.i.valid), fy.i.payload.a.eq(self.i.payload.b),
            fx.o.ready.eq(1), fy.o.ready.eq(1), tof.o.ready.eq(1),
            self.i.ready.eq(1),
        ]
        # ---- atan: iterative vectoring CORDIC (radian table) -----------------------------
        X = Signal(signed(XY_BITS))
        Y = Signal(signed(XY_BITS))
        Z = Signal(signed(Z_BITS))
        it = Signal(range(ITERATIONS + 1))
        busy = Signal()
        fin = Signal()
        sat = Signal()
        x0 = Signal(signed(XY_BITS))
        y0 = Signal(signed(XY_BITS))
        m.d.comb += [x0.eq(fx.o.payload.r << GUARD), y0.eq(fy.o.payload.r << GUARD)]
        table = Array(Const(int(v), signed(Z_BITS)) for v in ATAN_TABLE)
        m.d.sync += fin.eq(0)
        with m.If(fx.o.valid):
            left = x0 < 0
            up = y0 >= 0
            with m.If(left & up):
                m.d.sync += [X.eq(y0), Y.eq(-x0), Z.eq(HALF_PI_Z)]
            with m.Elif(left):
                m.d.sync += [X.eq(-y0), Y.eq(x0), Z.eq(-HALF_PI_Z)]
            with m.Else():
                m.d.sync += [X.eq(x0), Y.eq(y0), Z.eq(0)]
            m.d.sync += [it.eq(0), busy.eq(1),
                         sat.eq(fx.o.payload.overflow | fy.o.payload.overflow)]
        with m.Elif(busy):
            dx = Signal(signed(XY_BITS))
            dy = Signal(signed(XY_BITS))
            m.d.comb += [dx.eq(Y >> it), dy.eq(X >> it)]
            pos = Y >= 0
            with m.If(pos):
                m.d.sync += [X.eq(X + dx), Y.eq(Y - dy), Z.eq(Z + table[it])]
            with m.Else():
                m.d.sync += [X.eq(X - dx), Y.eq(Y + dy), Z.eq(Z - table[it])]
            m.d.sync += it.eq(it + 1)
            with m.If(it == ITERATIONS - 1):
                m.d.sync += [busy.eq(0), fin.eq(1)]
        # ---- 16to32: truncate Q2.14 toward zero to Q2.13, convert -------------------------
        sh = Z_FRAC - OUT_FRAC
        mag = Signal(Z_BITS)
        m.d.comb += mag.eq(Mux(Z < 0, -Z, Z) >> sh)
        ang = Signal(signed(WIDTH))
        m.d.comb += ang.eq(Mux(Z < 0, -mag, mag))
        m.d.comb += [tof.i.valid.eq(fin), tof.i.payload.x.eq(ang)]
        # saturation flag rides along the 4-cycle converter
        sat_pipe = Signal(Fp32FromFixed.LATENCY)
        m.d.sync += sat_pipe.eq(Cat(sat, sat_pipe[:-1]))
        m.d.comb += [self.o.valid.eq(tof.o.valid), self.o.payload.r.eq(tof.o.payload.r),
                     self.o.payload.saturated.eq(sat_pipe[-1])]
        return m


class AtanCircuit(wiring.Component):
    """Seed 003's arctangent circuit with its port list (table 3-7): ``in_a`` (cos),
    ``in_b`` (sin), ``in_atan_en`` -> ``out_result`` (radians), ``out_atan_finish``; plus
    ``out_saturated`` (an input did not fit Q2.13), an extension. Inputs are read in the
    cycle ``in_atan_en`` is high; ``out_atan_finish`` is high for one cycle,
    ``LATENCY`` cycles later, with ``out_result`` held until the next result."""

    LATENCY = AtanUnit.LATENCY + 1
    THROUGHPUT = AtanUnit.THROUGHPUT

    def __init__(self):
        super().__init__({"in_a": In(32), "in_b": In(32), "in_atan_en": In(1),
                          "out_result": Out(32), "out_atan_finish": Out(1),
                          "out_saturated": Out(1)})

    def elaborate(self, platform):
        m = Module()
        m.submodules.unit = u = AtanUnit()
        busy = Signal(range(AtanUnit.II + 1))
        go = self.in_atan_en & (busy == 0)
        m.d.comb += [u.i.valid.eq(go), u.i.payload.a.eq(self.in_a),
                     u.i.payload.b.eq(self.in_b), u.o.ready.eq(1)]
        with m.If(go):
            m.d.sync += busy.eq(AtanUnit.II - 1)
        with m.Elif(busy != 0):
            m.d.sync += busy.eq(busy - 1)
        m.d.sync += self.out_atan_finish.eq(u.o.valid)
        with m.If(u.o.valid):
            m.d.sync += [self.out_result.eq(u.o.payload.r),
                         self.out_saturated.eq(u.o.payload.saturated)]
        return m
