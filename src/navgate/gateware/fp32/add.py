"""Pipelined float32 adder/subtractor (one result per cycle).

Implements ``navgate.numerics.fp32.fp32_add`` / ``fp32_sub`` bit for bit:
flush-to-zero inputs, round to nearest even with an unbounded exponent, then
flush below 2**-126 and overflow at 2**128 (docs/gateware-fp32.md).

Architecture (classic single-path adder with guard/round/sticky, Goldberg,
"What every computer scientist should know about floating-point arithmetic",
1991, and Muller et al., Handbook of Floating-Point Arithmetic, 2nd ed., ch. 7):

1. unpack, swap so that |x| >= |y|, exponent difference, special cases;
2. align the smaller significand (right shift by the exponent difference,
   keeping guard and round bits and an OR-ed sticky bit);
3. add or subtract the 27-bit extended significands;
4. leading-zero count and normalising shift;
5. round to nearest even, exponent range check, pack.
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

    LATENCY = 5
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

        # ---- stage 1: unpack, swap, special cases ------------------------------
        a = unpack(m, self.i.payload.a, "a")
        b = unpack(m, self.i.payload.b, "b")
        sb = b.sign ^ self.i.payload.sub
        # Magnitude order on exponent||fraction.  A subnormal's fraction only
        # matters against another exponent-0 operand, and then both are zero.
        swap = self.i.payload.b[0:31] > self.i.payload.a[0:31]
        big_e = Mux(swap, b.exp, a.exp)
        small_e = Mux(swap, a.exp, b.exp)
        big_m = Mux(swap, b.mant, a.mant)
        small_m = Mux(swap, a.mant, b.mant)
        big_s = Mux(swap, sb, a.sign)
        eff_sub = a.sign ^ sb
        # Exponent difference; a zero operand's exponent field is 0, its significand 0.
        diff = Signal(8)
        m.d.comb += diff.eq(big_e - small_e)
        any_nan = a.nan | b.nan | (a.inf & b.inf & eff_sub)
        any_inf = a.inf | b.inf
        inf_sign = Mux(a.inf, a.sign, sb)
        both_zero_sign = a.sign & sb  # exact zero sum: -0 only for (-0) + (-0)

        s1_e = p.reg(big_e, "s1_e")
        s1_d = p.reg(Mux(diff > 27, 27, diff), "s1_d", unsigned(5))
        s1_bm = p.reg(big_m, "s1_bm")
        s1_sm = p.reg(small_m, "s1_sm")
        s1_s = p.reg(big_s, "s1_s")
        s1_sub = p.reg(eff_sub, "s1_sub")
        s1_nan = p.reg(any_nan, "s1_nan")
        s1_inf = p.reg(any_inf, "s1_inf")
        s1_infs = p.reg(inf_sign, "s1_infs")
        s1_zs = p.reg(both_zero_sign, "s1_zs")

        # ---- stage 2: align ----------------------------------------------------
        # (small_m << 3) >> d, with the bits shifted out beyond the guard and round
        # positions OR-ed into the sticky bit: those are small_m[0 : d-3], which
        # hold a one exactly when small_m has fewer than d - 3 trailing zeros.
        shifted = Signal(27)
        m.d.comb += shifted.eq(Cat(C(0, 3), s1_sm) >> s1_d)
        _, tz = leading_zeros(s1_sm[::-1])
        sticky = (tz + 3) < s1_d
        aligned = Cat(shifted[0] | sticky, shifted[1:27])
        s2_e = p.reg(s1_e, "s2_e")
        s2_bm = p.reg(s1_bm, "s2_bm")
        s2_al = p.reg(aligned, "s2_al", unsigned(27))
        s2_s = p.reg(s1_s, "s2_s")
        s2_sub = p.reg(s1_sub, "s2_sub")
        s2_nan = p.reg(s1_nan, "s2_nan")
        s2_inf = p.reg(s1_inf, "s2_inf")
        s2_infs = p.reg(s1_infs, "s2_infs")
        s2_zs = p.reg(s1_zs, "s2_zs")

        # ---- stage 3: add / subtract -------------------------------------------
        big_x = Cat(C(0, 3), s2_bm)  # 27 bits
        # One carry chain for both: x - y = x + ~y + 1.  For a subtraction the
        # result is non-negative (|x| >= |y|) and bit 27 is the discarded carry.
        raw = Signal(28)
        m.d.comb += raw.eq(big_x + (s2_al ^ s2_sub.replicate(27)) + s2_sub)
        total = Cat(raw[0:27], raw[27] & ~s2_sub)
        s3_e = p.reg(s2_e, "s3_e")
        s3_t = p.reg(total, "s3_t")
        s3_s = p.reg(s2_s, "s3_s")
        s3_nan = p.reg(s2_nan, "s3_nan")
        s3_inf = p.reg(s2_inf, "s3_inf")
        s3_infs = p.reg(s2_infs, "s3_infs")
        s3_zs = p.reg(s2_zs, "s3_zs")

        # ---- stage 4: normalise --------------------------------------------------
        _, lz = leading_zeros(s3_t[0:27])
        shl = Signal(27)
        m.d.comb += shl.eq(s3_t[0:27] << lz)
        carry = s3_t[27]
        # carry: significand = t[4:28], round = t[3], sticky = t[0:3]
        # else:  significand = shl[3:27], round = shl[2], sticky = shl[0:2]
        n_mant = Mux(carry, s3_t[4:28], shl[3:27])
        n_rnd = Mux(carry, s3_t[3], shl[2])
        n_sticky = Mux(carry, s3_t[0:3] != 0, shl[0:2] != 0)
        n_exp = Signal(signed(10))
        e9 = Cat(s3_e, C(0, 1)).as_signed()  # zero-extended, as signed
        m.d.comb += n_exp.eq(Mux(carry, e9 + 1, e9 - lz))
        s4_mant = p.reg(n_mant, "s4_mant", unsigned(24))
        s4_rnd = p.reg(n_rnd, "s4_rnd")
        s4_st = p.reg(n_sticky, "s4_st")
        s4_exp = p.reg(n_exp, "s4_exp")
        s4_zero = p.reg(s3_t == 0, "s4_zero")
        s4_s = p.reg(s3_s, "s4_s")
        s4_nan = p.reg(s3_nan, "s4_nan")
        s4_inf = p.reg(s3_inf, "s4_inf")
        s4_infs = p.reg(s3_infs, "s4_infs")
        s4_zs = p.reg(s3_zs, "s4_zs")

        # ---- stage 5: round, range check, specials --------------------------------
        rounded = round_pack(m, s4_s, s4_exp, s4_mant, s4_rnd, s4_st)
        result = Signal(32)
        with m.If(s4_nan):
            m.d.comb += result.eq(QNAN)
        with m.Elif(s4_inf):
            m.d.comb += result.eq(Cat(C(0, 23), C(0xFF, 8), s4_infs))
        with m.Elif(s4_zero):
            m.d.comb += result.eq(Cat(C(0, 31), s4_zs))
        with m.Else():
            m.d.comb += result.eq(rounded)
        r = p.reg(result, "s5_r")
        m.d.comb += self.o.payload.r.eq(r)

        p.finish()
        return m
