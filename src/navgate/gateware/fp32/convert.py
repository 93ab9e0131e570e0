"""Float32 <-> signed integer / fixed-point (Q format) converters, pipelined.

Implement ``navgate.numerics.fp32.fp32_from_fixed`` / ``fp32_from_int`` and
``fp32_to_fixed`` / ``fp32_to_int`` bit for bit (docs/gateware-fp32.md):

* fixed -> float: the exact value ``x * 2**-frac_bits`` rounded to nearest even
  to 24 bits, flushed to a signed zero below 2**-126 (0 -> +0);
* float -> fixed: ``round_ties_even(value * 2**frac_bits)`` saturated to the
  signed ``width``-bit range; ``overflow`` is set when the value saturated
  (including infinities) or the input was NaN (value 0).  Subnormal inputs
  read as zero.

One result per cycle.  Widths from 2 to 64 bits are supported.
"""

from amaranth.hdl import C, Cat, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.parameters import CheckedParameters

from ._common import Pipe, leading_zeros, round_pack, unpack

__all__ = ["Fp32FromFixed", "Fp32FromInt", "Fp32ToFixed", "Fp32ToInt"]


def _check_values(width, frac_bits=0):
    if not isinstance(width, int) or not 2 <= width <= 64:
        raise ValueError(f"width must be an integer in [2, 64], got {width!r}")
    if not isinstance(frac_bits, int) or not -256 <= frac_bits <= 256:
        raise ValueError(f"frac_bits must be an integer in [-256, 256], got {frac_bits!r}")


class Fp32FromFixed(CheckedParameters, wiring.Component):
    """Signed Q value ``x`` (``width`` bits, ``frac_bits`` fraction bits) -> float32.

    Input ``{x}``, output ``{r}``.  Stages: magnitude, leading-zero count,
    normalising shift, round and pack.
    """

    LATENCY = 4
    THROUGHPUT = 1.0

    @classmethod
    def check_parameters(cls, width, frac_bits=0):
        _check_values(width, frac_bits)

    def __init__(self, width: int = 32, frac_bits: int = 16):
        self.width = width
        self.frac_bits = frac_bits
        super().__init__({
            "i": In(stream.Signature(data.StructLayout({"x": signed(width)}))),
            "o": Out(stream.Signature(data.StructLayout({"r": unsigned(32)}))),
        })

    def elaborate(self, platform):
        m = Module()
        w = self.width
        p = Pipe(m, self.i, self.o, self.LATENCY)
        x = self.i.payload.x
        neg = x[w - 1]
        mag = Signal(w)
        m.d.comb += mag.eq(Mux(neg, -x, x))
        s1_mag = p.reg(mag, "s1_mag")
        s1_neg = p.reg(neg, "s1_neg")

        _, lz = leading_zeros(s1_mag)
        s2_mag = p.reg(s1_mag, "s2_mag")
        s2_lz = p.reg(lz, "s2_lz")
        s2_zero = p.reg(s1_mag == 0, "s2_zero")
        s2_neg = p.reg(s1_neg, "s2_neg")

        # Normalise (msb of norm set); value = norm * 2**(w - 1 - lz - frac_bits - (w - 1)).
        norm = Signal(w)
        m.d.comb += norm.eq(s2_mag << s2_lz)
        if w >= 25:
            mant = norm[w - 24:w]
            rnd = norm[w - 25]
            sticky = norm[0:w - 25] != 0 if w > 25 else C(0, 1)
        else:
            mant = Cat(C(0, 24 - w), norm)
            rnd = C(0, 1)
            sticky = C(0, 1)
        exp = Signal(signed(12))
        m.d.comb += exp.eq(w - 1 - self.frac_bits + 127 - s2_lz)
        s3_mant = p.reg(mant, "s3_mant", unsigned(24))
        s3_rnd = p.reg(rnd, "s3_rnd")
        s3_st = p.reg(sticky, "s3_st")
        s3_exp = p.reg(exp, "s3_exp")
        s3_zero = p.reg(s2_zero, "s3_zero")
        s3_neg = p.reg(s2_neg, "s3_neg")

        rounded = round_pack(m, s3_neg, s3_exp, s3_mant, s3_rnd, s3_st)
        r = p.reg(Mux(s3_zero, 0, rounded), "s4_r", unsigned(32))
        m.d.comb += self.o.payload.r.eq(r)
        p.finish()
        return m


class Fp32FromInt(Fp32FromFixed):
    """Signed ``width``-bit integer -> float32 (``Fp32FromFixed`` with no fraction bits)."""

    def __init__(self, width: int = 32):
        super().__init__(width=width, frac_bits=0)


class Fp32ToFixed(CheckedParameters, wiring.Component):
    """Float32 -> signed Q value (``width`` bits, ``frac_bits`` fraction bits).

    Input ``{a}``, output ``{r, overflow}``.  Stages: unpack and shift amount,
    shift decoding, left shift, right shift (with round and sticky bits),
    round, saturate and negate.
    """

    LATENCY = 6
    THROUGHPUT = 1.0

    @classmethod
    def check_parameters(cls, width, frac_bits=0):
        _check_values(width, frac_bits)

    def __init__(self, width: int = 32, frac_bits: int = 16):
        self.width = width
        self.frac_bits = frac_bits
        super().__init__({
            "i": In(stream.Signature(data.StructLayout({"a": unsigned(32)}))),
            "o": Out(stream.Signature(data.StructLayout({"r": signed(width),
                                                         "overflow": unsigned(1)}))),
        })

    def elaborate(self, platform):
        m = Module()
        w = self.width
        p = Pipe(m, self.i, self.o, self.LATENCY)
        a = unpack(m, self.i.payload.a, "a")
        # value = mant * 2**sh; t = mant * 2**(sh + 2) keeps a round bit and one
        # more bit below the integer point, the rest goes to sticky.
        sh2 = Signal(signed(12))  # sh + 2
        m.d.comb += sh2.eq(a.exp - 148 + self.frac_bits)
        s0_sh2 = p.reg(sh2, "s0_sh2")
        s0_m = p.reg(a.mant, "s0_m")
        s0_neg = p.reg(a.sign, "s0_neg", reset=True)
        s0_kind = p.reg(Cat(a.nan, a.inf, a.zero), "s0_kind", reset=True)

        # value >= 2**(23 + sh) > 2**w whenever sh > w - 23: always saturates.
        sh2 = s0_sh2
        big = sh2 > w - 21
        left = Signal(range(max(2, w - 20)))  # sh + 2 in [0, w - 21] (0 if w < 21)
        right = Signal(range(27))             # -(sh + 2) clamped to 26 (t = 0 then)
        m.d.comb += [
            left.eq(Mux((sh2 >= 0) & ~big, sh2, 0)),
            right.eq(Mux(sh2 >= 0, 0, Mux(sh2 < -26, 26, -sh2))),
        ]
        nan, inf, zero = s0_kind[0], s0_kind[1], s0_kind[2]
        s1_m = p.reg(s0_m, "s1_m")
        s1_left = p.reg(left, "s1_left")
        s1_right = p.reg(right, "s1_right")
        s1_neg = p.reg(s0_neg, "s1_neg", reset=True)
        s1_kind = p.reg(Cat(nan, inf | big & ~nan, zero), "s1_kind", reset=True)

        tw = max(w + 3, 24)  # t < 2**(24 + w - 21), or < 2**24 for small w
        # Left and right shifts in separate stages (at most one of them is non-zero).
        ml = p.reg(s1_m << s1_left, "s1b_ml", unsigned(tw))
        s1b_m = p.reg(s1_m, "s1b_m")
        s1b_right = p.reg(s1_right, "s1b_right")
        s1b_neg = p.reg(s1_neg, "s1b_neg", reset=True)
        s1b_kind = p.reg(s1_kind, "s1b_kind", reset=True)
        s1_m, s1_right, s1_neg, s1_kind = s1b_m, s1b_right, s1b_neg, s1b_kind
        t = Signal(tw)
        m.d.comb += t.eq(ml >> s1_right)
        # Bits shifted out on the right: mant[0:right] has a one iff the count of
        # trailing zeros of mant is below right.
        _, tz = leading_zeros(s1_m[::-1])
        lost = tz < s1_right
        s2_t = p.reg(t, "s2_t")
        s2_lost = p.reg(lost, "s2_lost")
        s2_neg = p.reg(s1_neg, "s2_neg")
        s2_kind = p.reg(s1_kind, "s2_kind")

        q = s2_t[2:]
        inc = s2_t[1] & (s2_t[0] | s2_lost | q[0])
        mag = Signal(tw - 1)
        m.d.comb += mag.eq(q + inc)
        s3_mag = p.reg(mag, "s3_mag")
        s3_neg = p.reg(s2_neg, "s3_neg")
        s3_kind = p.reg(s2_kind, "s3_kind")

        # Saturation tests and the negation side by side, then one selection.
        nan, sat_in, zero = s3_kind[0], s3_kind[1], s3_kind[2]
        too_big = Mux(s3_neg, s3_mag > (1 << (w - 1)), s3_mag > (1 << (w - 1)) - 1)
        over = ~nan & ~zero & (sat_in | too_big)
        neg_mag = Signal(w)
        m.d.comb += neg_mag.eq(-s3_mag)
        sat = Mux(s3_neg, C(1 << (w - 1), w), C((1 << (w - 1)) - 1, w))
        value = Signal(w)
        with m.If(nan | zero):
            m.d.comb += value.eq(0)
        with m.Elif(over):
            m.d.comb += value.eq(sat)
        with m.Elif(s3_neg):
            m.d.comb += value.eq(neg_mag)
        with m.Else():
            m.d.comb += value.eq(s3_mag)
        r = p.reg(value, "s4_r")
        flag = p.reg(over | nan, "s4_flag")
        m.d.comb += [self.o.payload.r.eq(r), self.o.payload.overflow.eq(flag)]
        p.finish()
        return m


class Fp32ToInt(Fp32ToFixed):
    """Float32 -> signed ``width``-bit integer (``Fp32ToFixed`` with no fraction bits)."""

    def __init__(self, width: int = 32):
        super().__init__(width=width, frac_bits=0)
