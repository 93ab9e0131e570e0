"""Pipelined float32 adder/subtractor (one result per cycle).

Implements ``navgate.numerics.fp32.fp32_add`` / ``fp32_sub`` bit for bit:
flush-to-zero inputs, round to nearest even with an unbounded exponent, then
flush below 2**-126 and overflow at 2**128 (docs/gateware-fp32.md).

Architecture (classic single-path adder with guard/round/sticky, Goldberg,
"What every computer scientist should know about floating-point arithmetic",
1991, and Muller et al., Handbook of Floating-Point Arithmetic, 2nd ed., ch. 7):

1. unpack, magnitude comparison, special cases;
2. swap so that |x| >= |y|, exponent difference, trailing
   zeros of the smaller significand;
3. align the smaller significand (right shift by the exponent difference,
   keeping guard and round bits and an OR-ed sticky bit);
4. add or subtract the 27-bit extended significands;
5. leading-zero counts of the two halves of the 28-bit sum (a carry-out
   counts as 0);
6. normalising left shift and exponent adjustment;
7. round to nearest even (increment) and exponent range tests;
8. special cases and final selection.

Eight short stages so that no stage chains two carry chains (the 150 MHz
goal on the ECP5 proxy).
"""

from amaranth.hdl import C, Cat, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data

from ._common import QNAN, Pipe, StreamOp, leading_zeros, round_split, unpack

__all__ = ["Fp32Add"]


class Fp32Add(StreamOp):
    """Float32 add/subtract: ``r = a + b`` (``sub == 0``) or ``r = a - b`` (``sub == 1``).

    Input payload ``{a, b, sub}``, output payload ``{r}``.
    """

    LATENCY = 8
    THROUGHPUT = 1.0
    IN_LAYOUT = data.StructLayout({"a": unsigned(32), "b": unsigned(32), "sub": unsigned(1)})
    OUT_LAYOUT = data.StructLayout({"r": unsigned(32)})

    def elaborate(self, platform):
        m = Module()
        p = Pipe(m, self.i, self.o, self.LATENCY)

        # ---- stage 1: unpack, magnitude order, special cases -------------------------
        a = unpack(m, self.i.payload.a, "a")
        b = unpack(m, self.i.payload.b, "b")
        sb = b.sign ^ self.i.payload.sub
        eff_sub = a.sign ^ sb
        # Magnitude order on exponent||fraction.  A subnormal's fraction only
        # matters against another exponent-0 operand, and then both are zero.
        swap = self.i.payload.b[0:31] > self.i.payload.a[0:31]
        any_nan = a.nan | b.nan | (a.inf & b.inf & eff_sub)
        any_inf = a.inf | b.inf
        inf_sign = Mux(a.inf, a.sign, sb)
        both_zero_sign = a.sign & sb  # exact zero sum: -0 only for (-0) + (-0)

        s1_ea, s1_eb = p.reg(a.exp, "s1_ea"), p.reg(b.exp, "s1_eb")
        s1_ma, s1_mb = p.reg(a.mant, "s1_ma"), p.reg(b.mant, "s1_mb")
        s1_sa, s1_sb = p.reg(a.sign, "s1_sa"), p.reg(sb, "s1_sb")
        s1_swap = p.reg(swap, "s1_swap")
        s1_sub = p.reg(eff_sub, "s1_sub")
        s1_kind = p.reg(Cat(any_nan, any_inf, inf_sign, both_zero_sign), "s1_kind")

        # ---- stage 2: swap so that |x| >= |y|, shift amount, trailing zeros ---------------
        big_e = Mux(s1_swap, s1_eb, s1_ea)
        small_e = Mux(s1_swap, s1_ea, s1_eb)
        small_m = Mux(s1_swap, s1_ma, s1_mb)
        d = Signal(8)
        m.d.comb += d.eq(big_e - small_e)  # non-negative after the swap
        _, tz = leading_zeros(small_m[::-1])  # trailing zeros, for the sticky bit
        s2_e = p.reg(big_e, "s2_e")
        s2_bm = p.reg(Mux(s1_swap, s1_mb, s1_ma), "s2_bm")
        s2_sm = p.reg(small_m, "s2_sm")
        s2_tz = p.reg(tz, "s2_tz")
        # Any shift of 27 or more empties the aligned significand; saturating to
        # 31 with an OR (no comparator on this path) is as good as min(d, 27).
        s2_d = p.reg(d[0:5] | d[5:8].any().replicate(5), "s2_d")
        s2_sz = p.reg(~small_m[23], "s2_sz")  # the smaller operand is zero
        s2_s = p.reg(Mux(s1_swap, s1_sb, s1_sa), "s2_s")
        s2_sub = p.reg(s1_sub, "s2_sub", reset=True)
        s2_kind = p.reg(s1_kind, "s2_kind", reset=True)

        # ---- stage 3: align ------------------------------------------------------------
        # (small_m << 3) >> d, with the bits shifted out beyond the guard and round
        # positions OR-ed into the sticky bit: those are small_m[0 : d-3], which
        # hold a one exactly when small_m has fewer than d - 3 trailing zeros.
        shifted = Signal(27)
        m.d.comb += shifted.eq(Cat(C(0, 3), s2_sm) >> s2_d)
        # tz + 3 < d  <=>  d - tz >= 4: one subtraction, then a sign and bit test.
        dt = Signal(signed(7))
        m.d.comb += dt.eq(s2_d - s2_tz)
        sticky = ~dt[6] & (dt[2:6] != 0) & ~s2_sz
        s3_al = p.reg(Cat(shifted[0] | sticky, shifted[1:27]), "s3_al", unsigned(27))
        s3_e = p.reg(s2_e, "s3_e", reset=True)
        s3_bm = p.reg(s2_bm, "s3_bm")
        s3_s = p.reg(s2_s, "s3_s", reset=True)
        s3_sub = p.reg(s2_sub, "s3_sub", reset=True)
        s3_kind = p.reg(s2_kind, "s3_kind", reset=True)

        # ---- stage 4: add / subtract ----------------------------------------------------
        # One carry chain for both: x - y = x + ~y + 1.  For a subtraction the
        # result is non-negative (|x| >= |y|) and bit 27 is the discarded carry.
        big_x = Cat(C(0, 3), s3_bm)  # 27 bits
        raw = Signal(28)
        m.d.comb += raw.eq(big_x + (s3_al ^ s3_sub.replicate(27)) + s3_sub)
        s4_t = p.reg(Cat(raw[0:27], raw[27] & ~s3_sub), "s4_t", unsigned(28))
        s4_e = p.reg(s3_e, "s4_e", reset=True)
        s4_s = p.reg(s3_s, "s4_s", reset=True)
        s4_kind = p.reg(s3_kind, "s4_kind", reset=True)

        # ---- stage 5: leading-zero counts of the two halves of the 28-bit sum ----------
        # A carry-out (t[27]) gives lz = 0, i.e. the one-place right shift of a
        # sum in [2, 4) falls out of the same left-shift path.
        z_hi, c_hi = leading_zeros(s4_t[12:28])
        _, c_lo = leading_zeros(s4_t[0:12])  # padded to 16 bits
        s5_zh = p.reg(z_hi, "s5_zh")
        s5_ch = p.reg(c_hi, "s5_ch")
        s5_cl = p.reg(c_lo, "s5_cl")
        s5_t = p.reg(s4_t, "s5_t")
        s5_e = p.reg(s4_e, "s5_e", reset=True)
        s5_s = p.reg(s4_s, "s5_s", reset=True)
        s5_kind = p.reg(s4_kind, "s5_kind", reset=True)

        # ---- stage 6: normalise ----------------------------------------------------------
        # lz = 16 * zh + (zh ? cl : ch); the shift by 16 needs only the registered zh.
        # significand = shl[4:28], round = shl[3], sticky = shl[0:3]; value exponent
        # is e + 1 - lz (the sum has its binary point after bit 26).
        low = Signal(4)
        m.d.comb += low.eq(Mux(s5_zh, s5_cl, s5_ch))
        t16 = Mux(s5_zh, s5_t << 16, s5_t)[0:28]
        shl = Signal(28)
        m.d.comb += shl.eq(t16 << low)
        s5_lz = Cat(low, s5_zh)
        n_exp = Signal(signed(10))
        e9 = Cat(s5_e, C(0, 1)).as_signed()  # zero-extended, as signed
        m.d.comb += n_exp.eq(e9 + 1 - s5_lz)
        s6_mant = p.reg(shl[4:28], "s6_mant", unsigned(24))
        s6_rnd = p.reg(shl[3], "s6_rnd")
        s6_st = p.reg(shl[0:3] != 0, "s6_st")
        s6_exp = p.reg(n_exp, "s6_exp")
        s6_zero = p.reg(s5_t == 0, "s6_zero")
        s6_s = p.reg(s5_s, "s6_s", reset=True)
        s6_kind = p.reg(s5_kind, "s6_kind", reset=True)

        # ---- stages 7 and 8: round, range check, specials ------------------------------
        rounded = round_split(m, p, s6_s, s6_exp, s6_mant, s6_rnd, s6_st)
        s7_zero = p.reg(s6_zero, "s7_zero", reset=True)
        s7_kind = p.reg(s6_kind, "s7_kind", reset=True)
        nan, inf, inf_s, zero_s = s7_kind[0], s7_kind[1], s7_kind[2], s7_kind[3]
        result = Signal(32)
        with m.If(nan):
            m.d.comb += result.eq(QNAN)
        with m.Elif(inf):
            m.d.comb += result.eq(Cat(C(0, 23), C(0xFF, 8), inf_s))
        with m.Elif(s7_zero):
            m.d.comb += result.eq(Cat(C(0, 31), zero_s))
        with m.Else():
            m.d.comb += result.eq(rounded)
        r = p.reg(result, "s8_r")
        m.d.comb += self.o.payload.r.eq(r)

        p.finish()
        return m
