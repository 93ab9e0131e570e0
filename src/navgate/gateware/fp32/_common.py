"""Shared building blocks for the float32 gateware cores.

The number format follows IEEE 754 binary32 with the navgate restrictions
(see ``navgate.numerics.fp32`` and docs/gateware-fp32.md): subnormal inputs are
read as zero of the same sign, results are rounded to nearest (ties to even) to
24 significant bits as if the exponent range were unbounded and then flushed to
a signed zero below 2**-126 or overflowed to a signed infinity at 2**128 and
above; every NaN result is the quiet NaN 0x7FC00000.

Pipelines here stall as a whole: all stage registers share one clock enable,
``en = ~o.valid | o.ready``, and ``i.ready = en``.  Valid bits ride along the
stages, so bubbles cost nothing when the output is ready.
"""

from amaranth.hdl import C, Cat, Module, Mux, Signal, Value
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

__all__ = ["QNAN", "Pipe", "StreamOp", "unpack", "leading_zeros", "round_pack",
           "round_split", "select_special", "finish_recurrence"]

QNAN = 0x7FC00000


class Pipe:
    """Helper that registers values behind one shared clock enable.

    ``reg(value)`` returns a reset-less register loaded from ``value`` whenever
    the pipeline advances.  ``reset=True`` gives it a synchronous reset, which
    keeps Xilinx synthesis from packing a chain of such registers into SRL16E
    shift-register LUTs (used for the flags and exponents that ride along the
    pipeline, so that they cost flip-flops instead of LUTs).  ``finish()`` emits
    the enable logic, the valid shift register and the stream handshake; call
    it once at the end of elaborate.
    """

    def __init__(self, m: Module, i, o, stages: int):
        self.m = m
        self.i = i
        self.o = o
        self.stages = stages
        self.en = Signal(name="pipe_en")
        self._stmts = []
        self._count = 0

    def reg(self, value, name=None, shape=None, reset=False):
        self._count += 1
        value = Value.cast(value) if shape is None else value
        if shape is None:
            shape = value.shape()
        sig = Signal(shape, name=name or f"p{self._count}", reset_less=not reset)
        self._stmts.append(sig.eq(value))
        return sig

    def finish(self):
        m = self.m
        valid = Signal(self.stages, name="pipe_valid")
        m.d.comb += [
            self.en.eq(~self.o.valid | self.o.ready),
            self.i.ready.eq(self.en),
            self.o.valid.eq(valid[-1]),
        ]
        with m.If(self.en):
            m.d.sync += valid.eq(Cat(self.i.valid, valid[:-1]))
            m.d.sync += self._stmts


def _wire(m: Module):
    """A stand-in for :meth:`Pipe.reg` that registers nothing (a named wire): the cores'
    ``steps_per_stage`` option chains several steps between two pipeline registers."""

    def wire(value, name=None, shape=None, reset=False):
        value = Value.cast(value) if shape is None else value
        sig = Signal(Value.cast(value).shape() if shape is None else shape, name=name)
        m.d.comb += sig.eq(value)
        return sig

    return wire


class Unpacked:
    """Fields and classification of one float32 operand (flush-to-zero)."""

    def __init__(self, m: Module, x, name: str):
        self.sign = Signal(name=f"{name}_sign")
        self.exp = Signal(8, name=f"{name}_exp")
        self.frac = Signal(23, name=f"{name}_frac")
        self.zero = Signal(name=f"{name}_zero")  # zero or subnormal
        self.inf = Signal(name=f"{name}_inf")
        self.nan = Signal(name=f"{name}_nan")
        self.mant = Signal(24, name=f"{name}_mant")  # hidden bit included, 0 when zero
        m.d.comb += [
            self.sign.eq(x[31]),
            self.exp.eq(x[23:31]),
            self.frac.eq(x[0:23]),
            self.zero.eq(self.exp == 0),
            self.inf.eq((self.exp == 0xFF) & (self.frac == 0)),
            self.nan.eq((self.exp == 0xFF) & (self.frac != 0)),
            self.mant.eq(Mux(self.exp == 0, 0, Cat(self.frac, C(1, 1)))),
        ]


def unpack(m: Module, x, name: str) -> Unpacked:
    return Unpacked(m, x, name)


def leading_zeros(v):
    """Leading-zero count of ``v`` as a balanced tree; returns (all_zero, count).

    ``len(v)`` is padded with ones at the bottom to a power of two, so for a
    non-zero ``v`` the count is exact and for ``v == 0`` ``all_zero`` is 0 only
    because of the padding (callers test ``v == 0`` separately where needed).
    """
    n = len(v)
    size = 1
    while size < n:
        size *= 2
    if size > n:
        v = Cat(C((1 << (size - n)) - 1, size - n), v)
    return _lzc(v)


def _lzc(v):
    n = len(v)
    if n == 1:
        return ~v[0], C(0, 0)
    if n == 2:
        return ~v[1] & ~v[0], ~v[1]
    lo, hi = v[: n // 2], v[n // 2 :]
    zh, ch = _lzc(hi)
    zl, cl = _lzc(lo)
    return zh & zl, Mux(zh, Cat(cl, C(1, 1)), Cat(ch, C(0, 1)))


def round_pack(m: Module, sign, exp, mant, rnd, sticky, name="rp"):
    """Round-to-nearest-even and pack.

    ``mant`` is the 24-bit significand (hidden bit set), ``exp`` the signed
    biased exponent of that significand, ``rnd`` the first discarded bit and
    ``sticky`` the OR of all further discarded bits.  Returns the packed word
    with underflow (rounded biased exponent <= 0 -> signed zero) and overflow
    (>= 255 -> signed infinity) applied.

    For speed the range check does not wait for the rounding increment: the
    increment carries out of the significand only when ``mant`` is all ones, so
    the rounded exponent is ``exp + carry`` with ``carry = inc & (mant == ~0)``,
    and both range tests are comparisons of ``exp`` with constants.  On a carry
    ``mant + 1`` wraps to zero, which is the right fraction for 2.0 -> 1.0 * 2.
    """
    inc = rnd & (sticky | mant[0])
    carry = Signal(name=f"{name}_carry")
    m.d.comb += carry.eq(inc & (mant == 0xFFFFFF))
    frac = Signal(23, name=f"{name}_frac")
    m.d.comb += frac.eq(mant[0:23] + inc)
    exp = exp.as_signed()
    under = (exp < 0) | ((exp == 0) & ~carry)
    over = (exp > 254) | ((exp == 254) & carry)
    out = Signal(32, name=f"{name}_out")
    with m.If(under):
        m.d.comb += out.eq(Cat(C(0, 31), sign))
    with m.Elif(over):
        m.d.comb += out.eq(Cat(C(0, 23), C(0xFF, 8), sign))
    with m.Else():
        m.d.comb += out.eq(Cat(frac, (exp + carry)[0:8], sign))
    return out


def round_split(m: Module, p: Pipe, sign, exp, mant, rnd, sticky, name="rs"):
    """:func:`round_pack` over two pipeline stages (the increment and the range
    tests, then the final selection); returns ``(packed, stage-2 registers)``
    so callers can register their own side signals in step."""
    inc = rnd & (sticky | mant[0])
    carry = inc & (mant == 0xFFFFFF)
    exp = exp.as_signed()
    frac = Signal(23, name=f"{name}_frac")
    m.d.comb += frac.eq(mant[0:23] + inc)
    r_frac = p.reg(frac, f"{name}_rfrac")
    r_exp8 = p.reg((exp + carry)[0:8], f"{name}_rexp8")
    r_under = p.reg((exp < 0) | ((exp == 0) & ~carry), f"{name}_runder")
    r_over = p.reg((exp > 254) | ((exp == 254) & carry), f"{name}_rover")
    r_sign = p.reg(sign, f"{name}_rsign")
    out = Signal(32, name=f"{name}_out")
    with m.If(r_under):
        m.d.comb += out.eq(Cat(C(0, 31), r_sign))
    with m.Elif(r_over):
        m.d.comb += out.eq(Cat(C(0, 23), C(0xFF, 8), r_sign))
    with m.Else():
        m.d.comb += out.eq(Cat(r_frac, r_exp8, r_sign))
    return out


class StreamOp(wiring.Component):
    """Base of the cores with fixed payload layouts: a stream input ``i`` of
    ``IN_LAYOUT`` and a stream output ``o`` of ``OUT_LAYOUT`` (class attributes)."""

    IN_LAYOUT: data.StructLayout
    OUT_LAYOUT: data.StructLayout

    def __init__(self):
        super().__init__({
            "i": In(stream.Signature(self.IN_LAYOUT)),
            "o": Out(stream.Signature(self.OUT_LAYOUT)),
        })


def select_special(m: Module, kind, sign, rounded, name: str = "sel"):
    """The result word: the canonical NaN, a signed infinity or a signed zero when
    ``kind`` (bits nan, inf, zero, in that priority) says so, else ``rounded``."""
    result = Signal(32, name=f"{name}_r")
    with m.If(kind[0]):
        m.d.comb += result.eq(QNAN)
    with m.Elif(kind[1]):
        m.d.comb += result.eq(Cat(C(0, 23), C(0xFF, 8), sign))
    with m.Elif(kind[2]):
        m.d.comb += result.eq(Cat(C(0, 31), sign))
    with m.Else():
        m.d.comb += result.eq(rounded)
    return result


def finish_recurrence(m: Module, p: Pipe, digits, remainder, exp, sign, kind, out_payload):
    """Common tail of the digit-recurrence cores (divide, square root).

    ``digits`` holds 25 result bits with the leading one at bit 24: the significand is
    ``digits[1:25]``, the round bit ``digits[0]``, and the sticky bit is set iff the final
    ``remainder`` is non-zero. One sticky stage, the two stages of :func:`round_split`, then
    the special-case selection, registered into ``out_payload``.
    """
    f_mant = p.reg(digits[1:25], "f_mant")
    f_rnd = p.reg(digits[0], "f_rnd")
    f_st = p.reg(remainder != 0, "f_st")
    exp = p.reg(exp, "f_exp")
    sign = p.reg(sign, "f_sign")
    kind = p.reg(kind, "f_kind")
    rounded = round_split(m, p, sign, exp, f_mant, f_rnd, f_st)
    kind = p.reg(kind, "g_kind", reset=True)
    sign = p.reg(sign, "g_sign", reset=True)
    out = p.reg(select_special(m, kind, sign, rounded), "out_r")
    m.d.comb += out_payload.eq(out)
