"""Iterative float32 square root: one radix-2 restoring step reused over 25 cycles.

Implements ``navgate.numerics.fp32.fp32_sqrt`` bit for bit, like the pipelined
:class:`~navgate.gateware.fp32.sqrt.Fp32Sqrt` (correctly rounded, flush-to-zero input,
sqrt(-0) = -0, sqrt(negative nonzero) = QNAN; docs/gateware-fp32.md), with one trial
subtractor instead of 25.

Algorithm (Ercegovac & Lang, "Digital Arithmetic", 2004, ch. 6; the bit-pair
"digit-by-digit" integer square root), the same as ``Fp32Sqrt``: the exponent is made even
by doubling the significand when it is odd, so the radicand lies in [1, 4) and the root in
[1, 2). A shift register hands the radicand's bit pairs (then zeros) to the step, which
computes ``rem = 4 * rem + pair``, and if ``rem >= 4 * root + 1`` subtracts it and appends a
1 to ``root``, else appends a 0. 25 steps give the hidden bit, 23 fraction bits and the
round bit; the final remainder is non-zero exactly when the root has a non-zero tail (the
sticky bit). A root is never out of range, so the range tests of the shared rounding never
fire (they stay for the shared code path).

Timing (see :mod:`._iterative`): 1 load + 25 recurrence + 1 round/pack register stages in
sequence: ``LATENCY = 27``; the round/pack cycle also accepts the next input, so
``INTERVAL = 26`` cycles between accepted inputs and ``THROUGHPUT = 1/26``.
``Fp32SqrtIter(steps_per_cycle=2)`` chains two steps per cycle (26 root bits in 13 cycles):
``LATENCY = 15``, ``INTERVAL = 14``.
"""

from fractions import Fraction

from amaranth.hdl import C, Cat, Module, Signal, signed, unsigned
from amaranth.lib import data

from ._common import unpack
from ._iterative import IterativeRecurrence

__all__ = ["Fp32SqrtIter"]


class Fp32SqrtIter(IterativeRecurrence):
    """Float32 square root ``r = sqrt(a)``, iterative (one root bit per cycle, 1/26 per cycle)."""

    SETUP_CYCLES = 0
    WORK_CYCLES = 25  # one per root bit
    LATENCY = WORK_CYCLES + 2     # 27
    INTERVAL = WORK_CYCLES + 1    # 26
    THROUGHPUT = Fraction(1, INTERVAL)
    IN_LAYOUT = data.StructLayout({"a": unsigned(32)})
    OUT_LAYOUT = data.StructLayout({"r": unsigned(32)})

    def datapath(self, m: Module, accept, work, count):
        nb = self.bits
        # Radicand N = v * 2**48 = m_adj * 2**25 with m_adj = mant << odd (25 bits); with one
        # zero padded below, its 13 bit pairs are rest[24:26], rest[22:24], ..., then zeros.
        rest = Signal(26, name="rest", reset_less=True)
        rem = Signal(nb + 1, name="rem", reset_less=True)  # rem <= 2 * root after each step
        root = Signal(nb, name="root", reset_less=True)    # root bits, shifted in at bit 0
        e = Signal(signed(10), name="e", reset_less=True)
        sign = Signal(name="sign", reset_less=True)
        kind = Signal(3, name="kind", reset_less=True)     # nan, inf, zero

        a = unpack(m, self.i.payload.a, "a")
        odd = ~a.exp[0]  # unbiased exponent a.exp - 127 is odd when a.exp is even
        e_unb = Signal(signed(10), name="e_unb")
        m.d.comb += e_unb.eq(a.exp - 127)

        # Before each step root < 2**(nb - 1) and rem <= 2 * root < 2**nb, so 4 * rem + pair
        # fits nb + 2 bits and 4 * root + 1 nb + 1 bits.
        rems, roots = [rem], [root]
        for j in range(self.steps_per_cycle):
            pair = rest[24 - 2 * j:26 - 2 * j]
            rem4 = Cat(pair, rems[j][0:nb])
            trial = Cat(C(1, 2), roots[j][0:nb - 1])
            diff = Signal(nb + 3, name=f"diff{j}")
            m.d.comb += diff.eq(rem4 - trial)
            bit = ~diff[nb + 2]
            rem_next = Signal(nb + 1, name=f"rem_next{j}")
            with m.If(bit):
                m.d.comb += rem_next.eq(diff)
            with m.Else():
                m.d.comb += rem_next.eq(rem4)
            rems.append(rem_next)
            roots.append(Cat(bit, roots[j][0:nb - 1]))

        with m.If(accept):
            m.d.sync += [
                rest.eq(Cat(C(0, 1), a.mant << odd)),
                rem.eq(0),
                root.eq(0),
                e.eq((e_unb >> 1) + 127),
                sign.eq(a.sign),
                kind.eq(Cat(a.nan | (a.sign & ~a.zero), a.inf, a.zero)),
            ]
        with m.Elif(work):
            m.d.sync += [
                rest.eq(rest << (2 * self.steps_per_cycle)),
                rem.eq(rems[-1]),
                root.eq(roots[-1]),
            ]

        return (sign, e, *self.split_result(root, rem), kind)
