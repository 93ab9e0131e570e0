"""Pipelined float32 adder/subtractor (one result per cycle).

Implements ``navgate.numerics.fp32.fp32_add`` / ``fp32_sub`` bit for bit:
flush-to-zero inputs, round to nearest even with an unbounded exponent, then
flush below 2**-126 and overflow at 2**128 (docs/gateware-fp32.md).

Architecture (classic single-path adder with guard/round/sticky, Goldberg,
"What every computer scientist should know about floating-point arithmetic",
1991, and Muller et al., Handbook of Floating-Point Arithmetic, 2nd ed., ch. 7):

1. unpack, magnitude comparison, both exponent differences, trailing-zero
   counts, special cases;
2. swap so that |x| >= |y|, clamp the shift amount;
3. align the smaller significand (right shift by the exponent difference,
   keeping guard and round bits and an OR-ed sticky bit);
4. add or subtract the 27-bit extended significands;
5. leading-zero count;
6. normalising shift and exponent adjustment;
7. round to nearest even, exponent range check, pack.

Seven short stages so that no stage chains two carry chains (the 150 MHz
goal on the ECP5 proxy).
"""

from amaranth.hdl import C, Cat, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ._common import QNAN, Pipe, leading_zeros, round_pack, unpack

__all__ = ["Fp32Add"]


class Fp32Add(wiring.Component):
    """Float32 add/subtract: ``r = a + b`` (``sub == 0``) or ``r = a - b`` (``sub == 1``).

    Input payload ``{a, b, sub}``, output payload ``{r}``.
    """

    LATENCY = 7
    THROUGHPUT = 1.0
    IN_LAYOUT = data.StructLayout({"a": unsigned(32), "b": unsigned(32), "sub": unsigned(1)})
    OUT_LAYOUT = data.StructLayout({"r": unsigned(32)})

    def __init__(self):
        super().__init__({
            "i": In(stream.Signature(self.IN_LAYOUT)),
            "o": Out(stream.Signature(self.OUT_LAYOUT)),
        })

    def elaborate(self, platform):
        m = Module()
        p = Pipe(m, self.i, self.o, self.LATENCY)

        # ---- stage 1: unpack, magnitude order, both exponent differences ------------
        a = unpack(m, self.i.payload.a, "a")
        b = unpack(m, self.i.payload.b, "b")
        sb = b.sign ^ self.i.payload.sub
        eff_sub = a.sign ^ sb
        # Magnitude order on exponent||fraction.  A subnormal's fraction only
        # matters against another exponent-0 operand, and then both are zero.
        swap = self.i.payload.b[0:31] > self.i.payload.a[0:31]
        # Both differences in parallel with the comparison; stage 2 picks one.
        dab = Signal(9)
        dba = Signal(9)
        m.d.comb += [dab.eq(a.exp - b.exp), dba.eq(b.exp - a.exp)]
        _, tz_a = leading_zeros(a.mant[::-1])  # trailing zeros, for the sticky bit
        _, tz_b = leading_zeros(b.mant[::-1])
        any_nan = a.nan | b.nan | (a.inf & b.inf & eff_sub)
        any_inf = a.inf | b.inf
        inf_sign = Mux(a.inf, a.sign, sb)
        both_zero_sign = a.sign & sb  # exact zero sum: -0 only for (-0) + (-0)

        s1_ea, s1_eb = p.reg(a.exp, "s1_ea"), p.reg(b.exp, "s1_eb")
        s1_ma, s1_mb = p.reg(a.mant, "s1_ma"), p.reg(b.mant, "s1_mb")
        s1_tza, s1_tzb = p.reg(tz_a, "s1_tza"), p.reg(tz_b, "s1_tzb")
        s1_sa, s1_sb = p.reg(a.sign, "s1_sa"), p.reg(sb, "s1_sb")
        s1_swap = p.reg(swap, "s1_swap")
        s1_dab, s1_dba = p.reg(dab, "s1_dab"), p.reg(dba, "s1_dba")
        s1_sub = p.reg(eff_sub, "s1_sub")
        s1_kind = p.reg(Cat(any_nan, any_inf, inf_sign, both_zero_sign), "s1_kind")

        # ---- stage 2: swap so that |x| >= |y|, clamp the shift ------------------------
        d = Mux(s1_swap, s1_dba, s1_dab)[0:8]  # non-negative after the swap
        s2_e = p.reg(Mux(s1_swap, s1_eb, s1_ea), "s2_e")
        s2_bm = p.reg(Mux(s1_swap, s1_mb, s1_ma), "s2_bm")
        s2_sm = p.reg(Mux(s1_swap, s1_ma, s1_mb), "s2_sm")
        s2_tz = p.reg(Mux(s1_swap, s1_tza, s1_tzb), "s2_tz")
        s2_d = p.reg(Mux(d > 27, 27, d), "s2_d", unsigned(5))
        s2_s = p.reg(Mux(s1_swap, s1_sb, s1_sa), "s2_s")
        s2_sub = p.reg(s1_sub, "s2_sub")
        s2_kind = p.reg(s1_kind, "s2_kind")

        # ---- stage 3: align ------------------------------------------------------------
        # (small_m << 3) >> d, with the bits shifted out beyond the guard and round
        # positions OR-ed into the sticky bit: those are small_m[0 : d-3], which
        # hold a one exactly when small_m has fewer than d - 3 trailing zeros.
        shifted = Signal(27)
        m.d.comb += shifted.eq(Cat(C(0, 3), s2_sm) >> s2_d)
        sticky = (s2_tz + 3) < s2_d
        s3_al = p.reg(Cat(shifted[0] | sticky, shifted[1:27]), "s3_al", unsigned(27))
        s3_e = p.reg(s2_e, "s3_e")
        s3_bm = p.reg(s2_bm, "s3_bm")
        s3_s = p.reg(s2_s, "s3_s")
        s3_sub = p.reg(s2_sub, "s3_sub")
        s3_kind = p.reg(s2_kind, "s3_kind")

        # ---- stage 4: add / subtract ----------------------------------------------------
        # One carry chain for both: x - y = x + ~y + 1.  For a subtraction the
        # result is non-negative (|x| >= |y|) and bit 27 is the discarded carry.
        big_x = Cat(C(0, 3), s3_bm)  # 27 bits
        raw = Signal(28)
        m.d.comb += raw.eq(big_x + (s3_al ^ s3_sub.replicate(27)) + s3_sub)
        s4_t = p.reg(Cat(raw[0:27], raw[27] & ~s3_sub), "s4_t", unsigned(28))
        s4_e = p.reg(s3_e, "s4_e")
        s4_s = p.reg(s3_s, "s4_s")
        s4_kind = p.reg(s3_kind, "s4_kind")

        # ---- stage 5: leading-zero count ------------------------------------------------
        _, lz = leading_zeros(s4_t[0:27])
        s5_lz = p.reg(lz, "s5_lz")
        s5_t = p.reg(s4_t, "s5_t")
        s5_e = p.reg(s4_e, "s5_e")
        s5_s = p.reg(s4_s, "s5_s")
        s5_kind = p.reg(s4_kind, "s5_kind")

        # ---- stage 6: normalise ----------------------------------------------------------
        shl = Signal(27)
        m.d.comb += shl.eq(s5_t[0:27] << s5_lz)
        carry = s5_t[27]
        # carry: significand = t[4:28], round = t[3], sticky = t[0:3]
        # else:  significand = shl[3:27], round = shl[2], sticky = shl[0:2]
        n_mant = Mux(carry, s5_t[4:28], shl[3:27])
        n_rnd = Mux(carry, s5_t[3], shl[2])
        n_sticky = Mux(carry, s5_t[0:3] != 0, shl[0:2] != 0)
        n_exp = Signal(signed(10))
        e9 = Cat(s5_e, C(0, 1)).as_signed()  # zero-extended, as signed
        m.d.comb += n_exp.eq(Mux(carry, e9 + 1, e9 - s5_lz))
        s6_mant = p.reg(n_mant, "s6_mant", unsigned(24))
        s6_rnd = p.reg(n_rnd, "s6_rnd")
        s6_st = p.reg(n_sticky, "s6_st")
        s6_exp = p.reg(n_exp, "s6_exp")
        s6_zero = p.reg(s5_t == 0, "s6_zero")
        s6_s = p.reg(s5_s, "s6_s")
        s6_kind = p.reg(s5_kind, "s6_kind")

        # ---- stage 7: round, range check, specials ------------------------------------------
        rounded = round_pack(m, s6_s, s6_exp, s6_mant, s6_rnd, s6_st)
        nan, inf, inf_s, zero_s = s6_kind[0], s6_kind[1], s6_kind[2], s6_kind[3]
        result = Signal(32)
        with m.If(nan):
            m.d.comb += result.eq(QNAN)
        with m.Elif(inf):
            m.d.comb += result.eq(Cat(C(0, 23), C(0xFF, 8), inf_s))
        with m.Elif(s6_zero):
            m.d.comb += result.eq(Cat(C(0, 31), zero_s))
        with m.Else():
            m.d.comb += result.eq(rounded)
        r = p.reg(result, "s7_r")
        m.d.comb += self.o.payload.r.eq(r)

        p.finish()
        return m
