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
``Fp32DivIter(steps_per_cycle=2)`` chains two steps per cycle (26 quotient bits in 13
cycles, the pre-normalisation using the first of the two): ``LATENCY = 16``,
``INTERVAL = 15``.
"""

from fractions import Fraction

from amaranth.hdl import Cat, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data

from ._common import unpack
from ._iterative import IterativeRecurrence

__all__ = ["Fp32DivIter"]


class Fp32DivIter(IterativeRecurrence):
    """Float32 divide ``r = a / b``, iterative (one quotient bit per cycle, 1/27 per cycle)."""

    SETUP_CYCLES = 1  # pre-normalisation
    WORK_CYCLES = SETUP_CYCLES + 25  # + 25 quotient bits
    LATENCY = WORK_CYCLES + 2     # 28
    INTERVAL = WORK_CYCLES + 1    # 27
    THROUGHPUT = Fraction(1, INTERVAL)
    IN_LAYOUT = data.StructLayout({"a": unsigned(32), "b": unsigned(32)})
    OUT_LAYOUT = data.StructLayout({"r": unsigned(32)})

    def datapath(self, m: Module, accept, work, count):
        nb = self.bits
        r = Signal(25, name="r", reset_less=True)       # partial remainder, r < 2 * d
        d = Signal(24, name="d", reset_less=True)       # divisor significand
        q = Signal(nb, name="q", reset_less=True)       # quotient bits, shifted in at bit 0
        e = Signal(signed(10), name="e", reset_less=True)
        sign = Signal(name="sign", reset_less=True)
        kind = Signal(3, name="kind", reset_less=True)  # nan, inf, zero

        a = unpack(m, self.i.payload.a, "a")
        b = unpack(m, self.i.payload.b, "b")

        # steps_per_cycle chained steps: rs[j] -> rs[j + 1], quotient bits bits[j]
        rs = [r]
        bits = []
        for j in range(self.steps_per_cycle):
            diff = Signal(26, name=f"diff{j}")
            m.d.comb += diff.eq(rs[j] - d)
            bit = ~diff[25]  # r >= d
            r_next = Signal(25, name=f"r_next{j}")
            with m.If(bit):
                m.d.comb += r_next.eq(diff[0:24] << 1)
            with m.Else():
                m.d.comb += r_next.eq(rs[j][0:24] << 1)
            rs.append(r_next)
            bits.append(bit)
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
            # q also shifts in the pre-normalisation cycle; those bits leave the register
            # by the end.
            m.d.sync += q.eq(Cat(*reversed(bits), q[:nb - len(bits)]))
            # Pre-normalisation: the first step's test r >= d is ma >= mb; keep r, or take
            # the first step's 2 * r.
            r_load = rs[1] if len(bits) == 1 else Mux(prenorm, rs[1], rs[-1])
            with m.If(~(prenorm & bits[0])):
                m.d.sync += r.eq(r_load)
            with m.If(prenorm & ~bits[0]):
                m.d.sync += e.eq(e - 1)

        return (sign, e, *self.split_result(q, r), kind)
