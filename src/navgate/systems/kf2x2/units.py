"""Shared arithmetic units of the 2x2 Kalman filter and its serial Goldschmidt reciprocal.

Reference: seed 004 (``fxp_mul.v``, ``fxp_add.v``, ``fxp_sub.v``, ``fxp_abs.v``,
``goldschmidt_struct.v``). The units are combinational, between the modules' registers, as
in the seed; operands arrive OR-ed from the modules (a module drives zeros when it does not
issue on a unit, so an AND-OR multiplexer replaces a select tree).

* :func:`q_mul`: ``sat((a * b) >> FRAC)`` and its overflow flag, bit-true to
  ``fixed_mul_trunc(a, b, fmt, mode="saturate")`` (:mod:`navgate.numerics.fixed`).
* :func:`q_alu`: add, subtract, absolute difference, saturating (``fixed_add``,
  ``fixed_sub``, ``fixed_abs(fixed_sub_full(...))``).
* :class:`GoldschmidtSerial`: :func:`navgate.numerics.goldschmidt.goldschmidt_reciprocal`
  (table seed, F = N, rounding to nearest) sequenced over ``2k + 4`` cycles, its ``2k``
  multiplies issued on a shared multiplier (multiplier 3 of the pool) instead of owning
  ``2k`` multipliers as the pipelined :class:`navgate.gateware.goldschmidt.GoldschmidtReciprocal`
  does (that one would cost 4 DSP48E1 more at N=20 and break the 8-DSP budget). The seed
  ROM contents come from ``goldschmidt_seed_table`` and the leading-one detector from
  :mod:`navgate.gateware.goldschmidt`, so the three faces share them.
"""

from __future__ import annotations

from amaranth import Array, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.fixed import saturate_value
from navgate.gateware.goldschmidt import leading_one
from navgate.numerics.goldschmidt import goldschmidt_seed_table

__all__ = ["q_mul", "q_alu", "ALU_ADD", "ALU_SUB", "ALU_ABSDIFF", "GoldschmidtSerial"]

ALU_ADD, ALU_SUB, ALU_ABSDIFF = 0, 1, 2


def q_mul(product, n: int, frac: int):
    """``(result, overflow)`` of the truncated, saturated Q(n, frac) product."""
    return saturate_value(product >> frac, n)


def q_alu(m: Module, a, b, op, n: int, name: str):
    """Saturating add / sub / |a - b| of signed n-bit a, b -> ``(result, overflow)``."""
    s = Signal(signed(n + 1), name=f"{name}_sum")
    d = Signal(signed(n + 1), name=f"{name}_dif")
    m.d.comb += [s.eq(a + b), d.eq(a - b)]
    ad = Mux(d[-1], -d, d)
    full = Signal(signed(n + 2), name=f"{name}_full")
    m.d.comb += full.eq(Mux(op == ALU_ADD, s, Mux(op == ALU_SUB, d, ad)))
    return saturate_value(full, n)


class GoldschmidtSerial(wiring.Component):
    """Serial Goldschmidt reciprocal 1/d in Q(n, frac) on a borrowed multiplier.

    ``start`` is high for one cycle with ``d`` valid; ``q``, ``div_zero``, ``overflow`` are
    registers, valid from ``LATENCY = 2k + 4`` cycles after the start until the next start.
    Cycle plan (l = cycles after start): 0 sign, |d|, leading one, normalised D; 1 seed
    x0 = ROM[D bits] (N = x0); 2 D <- (D x0) >> F; per iteration j < k: G = 2 - D
    registered and D <- (D G) >> F, then N <- (N G) >> F; last iteration N <- (N (2 - D))
    >> F; 2k+2 denormalising shift with rounding; 2k+3 saturation and sign.
    ``mul_a``, ``mul_b`` (unsigned F+2 bits, zero when idle) go to the shared multiplier,
    ``mul_p`` is its ``(a b) >> F``; ``mul_en`` marks the cycles that use it.
    """

    def __init__(self, n: int = 20, frac: int = 10, iterations: int = 1, seed_bits: int = 8):
        self.n, self.frac, self.iterations, self.seed_bits = n, frac, iterations, seed_bits
        self.F = n
        self.LATENCY = 2 * iterations + 4
        rw = self.F + 2
        super().__init__({
            "start": In(1), "d": In(signed(n)),
            "q": Out(signed(n)), "div_zero": Out(1), "overflow": Out(1),
            "mul_a": Out(unsigned(rw)), "mul_b": Out(unsigned(rw)), "mul_en": Out(1),
            "mul_p": In(unsigned(rw)),
        })

    def elaborate(self, platform):
        m = Module()
        w, F, frac, k = self.n, self.F, self.frac, self.iterations
        rw = F + 2
        L = self.LATENCY
        step = Signal(range(L + 1))
        run = Signal()
        with m.If(self.start):
            m.d.sync += [run.eq(1), step.eq(1)]
        with m.Elif(run):
            m.d.sync += step.eq(step + 1)
            with m.If(step == L - 1):
                m.d.sync += run.eq(0)
        neg = Signal()
        zero = Signal()
        sh = Signal(signed(max(F + w + 2, 2 * w + 2).bit_length() + 1))
        Dn = Signal(unsigned(F))
        N = Signal(unsigned(rw))
        D = Signal(unsigned(rw))
        G = Signal(unsigned(rw))
        # step 0: sign/magnitude and normalisation (model: a = |d|, D = a << (F-1-p))
        d = self.d
        d_zero = d == 0
        a = Mux(d_zero, 1, Mux(d[-1], -d, d))[:w]
        pd, lzd = leading_one(m, a, "kf_pd")
        with m.If(self.start):
            m.d.sync += [neg.eq(d[-1]), zero.eq(d_zero), sh.eq(2 * frac - pd - 1 - F),
                         Dn.eq((a << lzd)[:w] << (F - w))]
        # step 1: seed
        rom = Array(Const(int(v), unsigned(F + 1))
                    for v in goldschmidt_seed_table(self.seed_bits, F))
        index = Dn[F - 1 - self.seed_bits: F - 1] if self.seed_bits else 0
        two = Const(2 << F, unsigned(rw + 1))
        plan: list[tuple[int, str]] = [(2, "D0")]
        c = 3
        for j in range(1, k + 1):
            if j < k:
                plan += [(c, "DG"), (c + 1, "NG")]
                c += 2
            else:
                plan.append((c, "NLAST"))
                c += 1
        assert c == 2 * k + 2
        with m.If(run):
            with m.Switch(step):
                with m.Case(1):
                    m.d.sync += N.eq(rom[index])
                for cyc, what in plan:
                    with m.Case(cyc):
                        m.d.comb += self.mul_en.eq(1)
                        if what == "D0":
                            m.d.comb += [self.mul_a.eq(Dn), self.mul_b.eq(N)]
                            m.d.sync += D.eq(self.mul_p)
                        elif what == "DG":
                            g = (two - D)[:rw]
                            m.d.comb += [self.mul_a.eq(D), self.mul_b.eq(g)]
                            m.d.sync += [D.eq(self.mul_p), G.eq(g)]
                        elif what == "NG":
                            m.d.comb += [self.mul_a.eq(N), self.mul_b.eq(G)]
                            m.d.sync += N.eq(self.mul_p)
                        else:
                            m.d.comb += [self.mul_a.eq(N), self.mul_b.eq((two - D)[:rw])]
                            m.d.sync += N.eq(self.mul_p)
        # step 2k+2: denormalising shift and rounding (as navgate.gateware.goldschmidt)
        q_low = Signal(unsigned(w))
        big = Signal()
        left_amt = Signal(range(w + 1))
        right_m1 = Signal(range(max(2, F + w + 3)))
        m.d.comb += [left_amt.eq(Mux(sh[-1], 0, sh)), right_m1.eq(Mux(sh[-1], -sh - 1, 0))]
        left = N << left_amt
        right = ((N >> right_m1) + 1) >> 1
        shifted = Mux(sh[-1], right, left)
        # step 2k+3: saturation, sign, divide-by-zero override
        limit = Mux(neg, 1 << (w - 1), (1 << (w - 1)) - 1)
        over = big | (q_low > limit)
        q_mag = Mux(over, limit, q_low)
        value = Mux(neg, -q_mag, q_mag)
        with m.If(run):
            with m.If(step == 2 * k + 2):
                m.d.sync += [q_low.eq(shifted[:w]), big.eq(shifted[w:].any())]
            with m.If(step == 2 * k + 3):
                m.d.sync += [self.q.eq(Mux(zero, (1 << (w - 1)) - 1, value)),
                             self.overflow.eq(over & ~zero), self.div_zero.eq(zero)]
        return m
