"""Pipelined float32 divider: radix-2 restoring digit recurrence, fully unrolled.

Implements ``navgate.numerics.fp32.fp32_div`` bit for bit (correctly rounded,
flush-to-zero inputs, flush/overflow of results, x/0 = signed infinity,
0/0 = inf/inf = QNAN; docs/gateware-fp32.md).

Algorithm (Ercegovac & Lang, "Digital Arithmetic", 2004, ch. 5, restoring
division): the dividend significand is pre-normalised so that the quotient
lies in [1, 2) (``x = 2 * ma`` and exponent - 1 when ``ma < mb``); then 25
quotient bits (the hidden bit, 23 fraction bits and the round bit) are
produced one per pipeline stage by ``r >= d ? (q=1, r -= d) : q=0; r <<= 1``.
The final remainder is non-zero exactly when the discarded tail of the
quotient is, which gives the sticky bit for round-to-nearest-even.

Latency 28 cycles (1 unpack + 25 recurrence + 1 sticky + 1 round), one result
per cycle.
"""

from amaranth.hdl import C, Cat, Module, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ._common import QNAN, Pipe, round_pack, unpack

__all__ = ["Fp32Div"]


class Fp32Div(wiring.Component):
    """Float32 divide ``r = a / b``; input ``{a, b}``, output ``{r}``."""

    QUOTIENT_BITS = 25
    LATENCY = QUOTIENT_BITS + 3
    THROUGHPUT = 1.0
    IN_LAYOUT = data.StructLayout({"a": unsigned(32), "b": unsigned(32)})
    OUT_LAYOUT = data.StructLayout({"r": unsigned(32)})

    def __init__(self):
        super().__init__({
            "i": In(stream.Signature(self.IN_LAYOUT)),
            "o": Out(stream.Signature(self.OUT_LAYOUT)),
        })

    def elaborate(self, platform):
        m = Module()
        p = Pipe(m, self.i, self.o, self.LATENCY)

        # ---- stage 1: unpack, special cases, pre-normalise ------------------------
        a = unpack(m, self.i.payload.a, "a")
        b = unpack(m, self.i.payload.b, "b")
        sign = a.sign ^ b.sign
        nan = a.nan | b.nan | (a.inf & b.inf) | (a.zero & b.zero)
        inf = a.inf | b.zero  # (nan has priority)
        zero = a.zero | b.inf
        shift = a.mant < b.mant
        exp = Signal(signed(10))
        m.d.comb += exp.eq(a.exp - b.exp + 127 - shift)
        r = p.reg(a.mant << shift, "s1_r", unsigned(25))
        d = p.reg(b.mant, "s1_d")
        e = p.reg(exp, "s1_exp")
        s = p.reg(sign, "s1_sign")
        kind = p.reg(Cat(nan, inf, zero), "s1_kind")

        # ---- stages 2..26: one quotient bit per stage --------------------------------
        q = None
        for k in range(self.QUOTIENT_BITS):
            diff = Signal(26, name=f"q{k}_diff")
            m.d.comb += diff.eq(r - d)
            bit = ~diff[25]  # r >= d
            nxt = Signal(25, name=f"q{k}_next")
            with m.If(bit):
                m.d.comb += nxt.eq(diff[0:24] << 1)
            with m.Else():
                m.d.comb += nxt.eq(r[0:24] << 1)
            q = p.reg(bit if q is None else Cat(bit, q), f"q{k}_q")
            r = p.reg(nxt, f"q{k}_r", unsigned(25))
            if k != self.QUOTIENT_BITS - 1:
                d = p.reg(d, f"q{k}_d")
            e = p.reg(e, f"q{k}_exp")
            s = p.reg(s, f"q{k}_sign")
            kind = p.reg(kind, f"q{k}_kind")

        # ---- sticky stage: the remainder is non-zero iff the quotient's tail is ---------
        # q[24] == 1 (quotient in [1, 2)); significand q[1:25], round bit q[0].
        f_mant = p.reg(q[1:25], "f_mant")
        f_rnd = p.reg(q[0], "f_rnd")
        f_st = p.reg(r != 0, "f_st")
        e = p.reg(e, "f_exp")
        s = p.reg(s, "f_sign")
        kind = p.reg(kind, "f_kind")

        # ---- last stage: round, range check, pack --------------------------------------
        rounded = round_pack(m, s, e, f_mant, f_rnd, f_st)
        result = Signal(32)
        with m.If(kind[0]):
            m.d.comb += result.eq(QNAN)
        with m.Elif(kind[1]):
            m.d.comb += result.eq(Cat(C(0, 23), C(0xFF, 8), s))
        with m.Elif(kind[2]):
            m.d.comb += result.eq(Cat(C(0, 31), s))
        with m.Else():
            m.d.comb += result.eq(rounded)
        out = p.reg(result, "out_r")
        m.d.comb += self.o.payload.r.eq(out)

        p.finish()
        return m
