"""Iterative float32 divider: one radix-2 restoring step reused over 26 cycles.

Implements ``navgate.numerics.fp32.fp32_div`` bit for bit, like the pipelined
:class:`~navgate.gateware.fp32.div.Fp32Div` (correctly rounded, flush-to-zero inputs,
flush/overflow of results, x/0 = signed infinity, 0/0 = inf/inf = QNAN;
docs/gateware-fp32.md), with one subtractor instead of 25.

Algorithm (Ercegovac & Lang, "Digital Arithmetic", 2004, ch. 5, restoring division), the
same as ``Fp32Div``: the divisor significand ``d`` and the partial remainder ``r`` (first the
dividend significand) live in registers; a step computes ``r - d`` and, if it is not
negative, sets the quotient bit and keeps the difference: ``q = r >= d; r = 2 * (q ? r - d
: r)``. The pre-normalisation (``r = 2 * ma`` and exponent - 1 when ``ma < mb``, so that
the quotient lies in [1, 2)) is the first cycle of the same datapath: ``r >= d`` is tested
by the same subtractor, ``r`` doubles through the same shifter when ``ma < mb`` and its
register simply does not load when ``ma >= mb``. Then 25 steps give the quotient bits
(hidden bit, 23 fraction bits, round bit) and the final remainder, non-zero exactly when the
discarded tail is (the sticky bit).

Timing (see :mod:`._iterative`): 1 load + 1 pre-normalise + 25 recurrence + 1 round/pack
register stages in sequence: ``LATENCY = 28``; the round/pack cycle also accepts the next
input, so ``INTERVAL = 27`` cycles between accepted inputs and ``THROUGHPUT = 1/27``.
"""

from fractions import Fraction

from amaranth.hdl import Cat, Module, Signal, signed, unsigned
from amaranth.lib import data

from ._common import unpack
from ._iterative import IterativeRecurrence

__all__ = ["Fp32DivIter"]


class Fp32DivIter(IterativeRecurrence):
    """Float32 divide ``r = a / b``, iterative (one quotient bit per cycle, 1/27 per cycle)."""

    QUOTIENT_BITS = 25
    WORK_CYCLES = QUOTIENT_BITS + 1  # pre-normalisation + 25 quotient bits
    LATENCY = WORK_CYCLES + 2     # 28
    INTERVAL = WORK_CYCLES + 1    # 27
    THROUGHPUT = Fraction(1, INTERVAL)
    IN_LAYOUT = data.StructLayout({"a": unsigned(32), "b": unsigned(32)})
    OUT_LAYOUT = data.StructLayout({"r": unsigned(32)})

    def datapath(self, m: Module, accept, work, count):
        r = Signal(25, name="r", reset_less=True)       # partial remainder, r < 2 * d
        d = Signal(24, name="d", reset_less=True)       # divisor significand
        q = Signal(25, name="q", reset_less=True)       # quotient bits, shifted in at bit 0
        e = Signal(signed(10), name="e", reset_less=True)
        sign = Signal(name="sign", reset_less=True)
        kind = Signal(3, name="kind", reset_less=True)  # nan, inf, zero

        a = unpack(m, self.i.payload.a, "a")
        b = unpack(m, self.i.payload.b, "b")

        diff = Signal(26, name="diff")
        m.d.comb += diff.eq(r - d)
        bit = ~diff[25]  # r >= d
        r_next = Signal(25, name="r_next")
        with m.If(bit):
            m.d.comb += r_next.eq(diff[0:24] << 1)
        with m.Else():
            m.d.comb += r_next.eq(r[0:24] << 1)
        prenorm = count == 0

        with m.If(accept):
            m.d.sync += [
                r.eq(a.mant),
                d.eq(b.mant),
                e.eq(a.exp - b.exp + 127),
                sign.eq(a.sign ^ b.sign),
                kind.eq(Cat(a.nan | b.nan | (a.inf & b.inf) | (a.zero & b.zero),
                            a.inf | b.zero,
                            a.zero | b.inf)),
            ]
        with m.Elif(work):
            # q also shifts in the pre-normalisation cycle; that bit leaves the 25-bit
            # register by the end.
            m.d.sync += q.eq(Cat(bit, q[:-1]))
            with m.If(~(prenorm & bit)):
                m.d.sync += r.eq(r_next)
            with m.If(prenorm & ~bit):
                m.d.sync += e.eq(e - 1)

        return sign, e, q[1:25], q[0], r != 0, kind
