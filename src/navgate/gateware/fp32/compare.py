"""Float32 comparison (one result per cycle, latency 2).

Implements ``navgate.numerics.fp32.fp32_compare`` bit for bit: IEEE ordering
after the input flush (a subnormal equals zero, -0 == +0); a NaN operand
makes the pair unordered and clears ``lt``, ``eq`` and ``gt``.  Exactly one
output bit is set per result.
"""

from amaranth.hdl import Cat, Module, Mux, unsigned
from amaranth.lib import data

from ._common import Pipe, StreamOp, unpack

__all__ = ["Fp32Compare"]


class Fp32Compare(StreamOp):
    """Compare ``a`` with ``b``; input ``{a, b}``, output ``{lt, equal, gt, unordered}``.

    The model's ``eq`` is called ``equal`` here: a layout field named ``eq``
    would shadow ``View.eq``.
    """

    LATENCY = 2
    THROUGHPUT = 1.0
    IN_LAYOUT = data.StructLayout({"a": unsigned(32), "b": unsigned(32)})
    OUT_LAYOUT = data.StructLayout({"lt": unsigned(1), "equal": unsigned(1), "gt": unsigned(1),
                                    "unordered": unsigned(1)})

    def elaborate(self, platform):
        m = Module()
        p = Pipe(m, self.i, self.o, self.LATENCY)
        x, y = self.i.payload.a, self.i.payload.b
        a = unpack(m, x, "a")
        b = unpack(m, y, "b")
        # Stage 1: raw 31-bit magnitude comparisons, in parallel with the
        # classification (the flush is applied in stage 2, off the carry chain).
        s_lt = p.reg(x[0:31] < y[0:31], "s1_lt")
        s_eq = p.reg(x[0:31] == y[0:31], "s1_eq")
        s_za, s_zb = p.reg(a.zero, "s1_za"), p.reg(b.zero, "s1_zb")
        s_sa, s_sb = p.reg(a.sign, "s1_sa"), p.reg(b.sign, "s1_sb")
        unordered = p.reg(a.nan | b.nan, "s1_unordered")

        # Stage 2: magnitudes with subnormals flushed (a zero's sign does not matter).
        mag_eq = Mux(s_za | s_zb, s_za & s_zb, s_eq)
        mag_lt = Mux(s_za | s_zb, s_za & ~s_zb, s_lt)
        neg_a = s_sa & ~s_za
        neg_b = s_sb & ~s_zb
        eq = mag_eq & (neg_a == neg_b)
        # Different signs: the negative one is smaller (both non-zero or one zero).
        lt = Mux(neg_a != neg_b, neg_a, Mux(neg_a, ~mag_lt & ~mag_eq, mag_lt))
        lt_o = ~unordered & lt & ~eq
        eq_o = ~unordered & eq
        gt_o = ~unordered & ~lt & ~eq
        res = p.reg(Cat(lt_o, eq_o, gt_o, unordered), "res")
        m.d.comb += self.o.payload.as_value().eq(res)
        p.finish()
        return m
