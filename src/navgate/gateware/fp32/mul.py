"""Pipelined float32 multiplier (one result per cycle).

Implements ``navgate.numerics.fp32.fp32_mul`` bit for bit (flush-to-zero
inputs, round to nearest even with unbounded exponent, then flush/overflow;
docs/gateware-fp32.md).

The 24x24-bit significand product is split into two DSP-sized partial
products, ``ma * mb[0:17]`` (24x17) and ``ma * mb[17:24]`` (24x7); each fits
one Xilinx DSP48E1 (25x18 signed multiplier, UG479) or one ECP5 MULT18X18D
pair, and the operand, product and sum registers sit where the DSP's A/B, M
and P registers are so synthesis can absorb them.

Stages: 1 unpack/exponent sum/special cases, 2 partial products, 3 partial
product sum, 4 normalise (product in [1, 4)), 5 round to nearest even, range
check and pack.
"""

from amaranth.hdl import Cat, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data

from ._common import Pipe, StreamOp, round_pack, select_special, unpack

__all__ = ["Fp32Mul"]


class Fp32Mul(StreamOp):
    """Float32 multiply ``r = a * b``; input ``{a, b}``, output ``{r}``."""

    LATENCY = 5
    THROUGHPUT = 1.0
    IN_LAYOUT = data.StructLayout({"a": unsigned(32), "b": unsigned(32)})
    OUT_LAYOUT = data.StructLayout({"r": unsigned(32)})

    def elaborate(self, platform):
        m = Module()
        p = Pipe(m, self.i, self.o, self.LATENCY)

        # ---- stage 1: unpack ----------------------------------------------------
        a = unpack(m, self.i.payload.a, "a")
        b = unpack(m, self.i.payload.b, "b")
        sign = a.sign ^ b.sign
        nan = a.nan | b.nan | (a.inf & b.zero) | (a.zero & b.inf)
        inf = a.inf | b.inf
        zero = a.zero | b.zero
        # Biased exponent of the product when the significand product is in [1, 2).
        exp = Signal(signed(10))
        m.d.comb += exp.eq(a.exp + b.exp - 127)
        s1_ma = p.reg(a.mant, "s1_ma")
        s1_mb = p.reg(b.mant, "s1_mb")
        s1_exp = p.reg(exp, "s1_exp")
        s1_sign = p.reg(sign, "s1_sign")
        s1_kind = p.reg(Cat(nan, inf, zero), "s1_kind")

        # ---- stage 2: two DSP-sized partial products -----------------------------
        s2_lo = p.reg(s1_ma * s1_mb[0:17], "s2_lo", unsigned(41))
        s2_hi = p.reg(s1_ma * s1_mb[17:24], "s2_hi", unsigned(31))
        s2_exp = p.reg(s1_exp, "s2_exp", reset=True)
        s2_sign = p.reg(s1_sign, "s2_sign", reset=True)
        s2_kind = p.reg(s1_kind, "s2_kind", reset=True)

        # ---- stage 3: product = lo + (hi << 17) ------------------------------------
        # The low 17 bits pass through; the upper part is hi + (lo >> 17), which
        # is the DSP48E1 cascade form P = A*B + (PCIN >> 17).
        s3_prod = p.reg(Cat(s2_lo[0:17], s2_hi + s2_lo[17:41]), "s3_prod", unsigned(48))
        s3_exp = p.reg(s2_exp, "s3_exp", reset=True)
        s3_sign = p.reg(s2_sign, "s3_sign", reset=True)
        s3_kind = p.reg(s2_kind, "s3_kind", reset=True)

        # ---- stage 4: normalise (product in [1, 4)) ------------------------------------
        top = s3_prod[47]
        exp4 = Signal(signed(11))
        m.d.comb += exp4.eq(s3_exp + top)
        s4_mant = p.reg(Mux(top, s3_prod[24:48], s3_prod[23:47]), "s4_mant", unsigned(24))
        s4_rnd = p.reg(Mux(top, s3_prod[23], s3_prod[22]), "s4_rnd")
        s4_st = p.reg((s3_prod[0:22] != 0) | (top & s3_prod[22]), "s4_st")
        s4_exp = p.reg(exp4, "s4_exp")
        s4_sign = p.reg(s3_sign, "s4_sign", reset=True)
        s4_kind = p.reg(s3_kind, "s4_kind", reset=True)

        # ---- stage 5: round, range check, special cases, pack -----------------------------
        rounded = round_pack(m, s4_sign, s4_exp, s4_mant, s4_rnd, s4_st)
        r = p.reg(select_special(m, s4_kind, s4_sign, rounded), "s5_r")
        m.d.comb += self.o.payload.r.eq(r)

        p.finish()
        return m
