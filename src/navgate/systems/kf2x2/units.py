"""Shared arithmetic units of the 2x2 Kalman filter and its serial Goldschmidt reciprocal.

Reference: seed 004 (``fxp_mul.v``, ``fxp_add.v``, ``fxp_sub.v``, ``fxp_abs.v``,
``goldschmidt_struct.v``). :func:`q_mul` and :func:`q_alu` are the combinational result
logic; :mod:`navgate.systems.kf2x2.modules` puts them between operand registers and (for the
multiplier) a raw product register, so no path crosses a multiplier and an adder in one
cycle (the re-timing of docs/seed004-kf2x2.md, "Timing").

* :func:`q_mul`: ``sat((a * b) >> FRAC)`` and its overflow flag, bit-true to
  ``fixed_mul_trunc(a, b, fmt, mode="saturate")`` (:mod:`navgate.numerics.fixed`).
* :func:`alu_results`: add and subtract on one carry chain (the subtrahend is loaded
  complemented, the carry-in is a registered control word), absolute difference on its
  own pair of chains, each result saturated (``fixed_add``, ``fixed_sub``,
  ``fixed_abs(fixed_sub_full(...))``); no op code is decoded behind the adder.
* :func:`saturate_bits`: the saturation as bit tests (sign and the bits above the target
  width), no comparator.
* :class:`GoldschmidtSerial`: :func:`navgate.numerics.goldschmidt.goldschmidt_reciprocal`
  (table seed, F = N, rounding to nearest) sequenced over :func:`divider_plan` cycles, its
  ``2k`` multiplies issued on a shared, pipelined multiplier (multiplier 3 of the pool)
  instead of owning ``2k`` multipliers as the pipelined
  :class:`navgate.gateware.goldschmidt.GoldschmidtReciprocal` does (that one would cost
  4 DSP48E1 more at N=20 and break the 8-DSP budget). The seed ROM contents come from
  ``goldschmidt_seed_table`` and the leading-one detector from
  :mod:`navgate.gateware.goldschmidt`, so the three faces share them.
"""

from __future__ import annotations

from amaranth import Array, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.goldschmidt import leading_one
from navgate.gateware.parameters import CheckedParameters
from navgate.numerics.goldschmidt import goldschmidt_seed_table

__all__ = ["q_mul", "alu_results", "saturate_bits", "ALU_KINDS", "Control",
           "GoldschmidtSerial", "divider_plan"]

#: the operation kinds an adder/subtractor unit computes
ALU_KINDS = ("add", "sub", "absdiff")


def saturate_bits(value, width: int):
    """``(clamped, overflow)`` of signed ``value`` clamped to ``signed(width)``.

    The same function as :func:`navgate.gateware.fixed.saturate_value`, written as bit tests:
    the value fits when every bit from ``width - 1`` up equals the sign; otherwise it is
    clamped to the limit of its sign. (A comparison with a constant can be mapped to a carry
    chain; these are a few LUT levels.)"""
    if len(value) <= width:
        return value.as_signed(), Const(0, 1)
    top = value[width - 1:]
    sign = value[-1]
    overflow = ~(top.all() | ~top.any())
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    result = Mux(overflow, Mux(sign, lo, hi), value[:width].as_signed())
    return result[:width].as_signed(), overflow


def q_mul(product, n: int, frac: int):
    """``(result, overflow)`` of the truncated, saturated Q(n, frac) product."""
    return saturate_bits(product >> frac, n)


def alu_results(m: Module, a, b, cin, kinds, n: int, name: str) -> dict:
    """Saturating results of an adder/subtractor unit with operand registers ``a``, ``b``.

    ``kinds``: the operation kinds scheduled on the unit. Returns ``{"addsub": (result,
    overflow)}`` if it adds or subtracts, and ``{"absdiff": ...}`` if it takes |a - b|.

    * add and subtract share one carry chain, ``a + b + cin``: for a subtraction the operand
      register ``b`` was loaded with the one's complement of the subtrahend and ``cin`` (a
      registered control word) is 1, so the sum is ``a - b``; no op code is decoded behind
      the adder. The (n + 1)-bit sum overflows n bits exactly when its top two bits differ.
    * ``absdiff`` computes ``a - b`` and ``b - a`` side by side and keeps the non-negative
      one (instead of negating the difference behind the subtraction): ``|a - b| <= 2**n - 1``
      fits n bits unsigned and overflows exactly when bit n - 1 is set.

    Bit-true to ``fixed_add``, ``fixed_sub`` and ``fixed_abs(fixed_sub_full(...))`` of
    :mod:`navgate.numerics.fixed` (saturating)."""
    for kind in kinds:
        if kind not in ALU_KINDS:
            raise ValueError(f"unknown ALU kind {kind!r}")
    out = {}
    if "add" in kinds or "sub" in kinds:
        s = Signal(signed(n + 1), name=f"{name}_sum")
        m.d.comb += s.eq(a + b + cin)
        out["addsub"] = saturate_bits(s, n)
    if "absdiff" in kinds:
        d = Signal(signed(n + 1), name=f"{name}_dif")
        e = Signal(signed(n + 1), name=f"{name}_rdif")
        m.d.comb += [d.eq(a - b), e.eq(b - a)]
        mag = Signal(unsigned(n), name=f"{name}_mag")  # |a - b| < 2**n
        m.d.comb += mag.eq(Mux(d[-1], e, d)[:n])
        overflow = mag[n - 1]
        out["absdiff"] = (Mux(overflow, (1 << (n - 1)) - 1, mag)[:n].as_signed(), overflow)
    return out


class Control:
    """Registered one-hot control of a sequence of ``length`` cycles started by ``go``.

    ``phase[c]`` is high in cycle c after ``go`` (``phase[0]`` is ``go`` itself, the others
    are a shift register). :meth:`at` returns a control word high exactly in the given
    cycles: a register loaded with the OR of the phase bits one cycle earlier (``go`` is
    OR-ed in when cycle 0 is among them, since nothing can be registered before the start).
    No counter is decoded anywhere.
    """

    def __init__(self, m: Module, go, length: int, name: str = "ph"):
        self.m, self.go, self.length, self.name = m, go, length, name
        self.phase = [go]
        for c in range(1, length):
            bit = Signal(name=f"{name}{c}")
            m.d.sync += bit.eq(self.phase[c - 1])
            self.phase.append(bit)
        self._words: dict[frozenset, object] = {}

    def at(self, cycles):
        cycles = frozenset(cycles)
        if not cycles:
            raise ValueError("a control word needs at least one cycle")
        if max(cycles) >= self.length or min(cycles) < 0:
            raise ValueError(f"cycle outside the frame 0..{self.length - 1}: {sorted(cycles)}")
        if cycles in self._words:
            return self._words[cycles]
        later = sorted(c for c in cycles if c >= 1)
        word = None
        if later:
            reg = Signal(name=f"{self.name}_w{len(self._words)}")
            acc = 0
            for c in later:
                acc = acc | self.phase[c - 1]
            self.m.d.sync += reg.eq(acc)
            word = reg
        if 0 in cycles:
            word = self.go if word is None else (self.go | word)
        self._words[cycles] = word
        return word


def divider_plan(iterations: int) -> tuple[list[int], int]:
    """(cycles after the start in which the divider loads the shared multiplier, latency).

    The latency is the cycle (after the start) in which the result is forwarded; the ``q``
    register holds it from the next cycle on."""
    k = iterations
    if k == 1:
        offsets = [2, 4]
    else:
        offsets = [2]
        for i in range(k - 1):
            offsets += [5 + 3 * i, 6 + 3 * i]
        offsets.append(5 + 3 * (k - 2) + 4)
    return offsets, offsets[-1] + 3


class GoldschmidtSerial(CheckedParameters, wiring.Component):
    """Serial Goldschmidt reciprocal 1/d in Q(n, frac) on a borrowed, pipelined multiplier.

    ``start`` is high for one cycle with ``d`` valid (``d`` is registered then). The shared
    multiplier registers its operands when ``mul_load`` is high (``mul_a``, ``mul_b``:
    unsigned F+1 bits, zero otherwise: every operand is below 2**(F+1), since Dn < 1,
    x0 = 2 / (lo + hi) < 2, every G = 2 - D is within the seed error of 1 and every
    intermediate N = x0 G1 G2 ... < 2, e.g. N1 = x0 (2 - x0 Dn) <= 1 / Dn <= 2 with
    equality only at x0 = 2) and its raw product one cycle later; ``mul_p`` is that
    product's ``>> F``, available two cycles after the load. Plan (s = cycles after
    the start, :func:`divider_plan`): s1 sign, |d|, leading one, normalised D; s2 seed
    x0 = ROM[D bits] (N = x0) and load D x0; k = 1: s4 load N x (2 - D) with ``2 - D``
    computed from the product straight into the operand register; k > 1: D and the
    registered ``G = 2 - D`` at s4, then per middle iteration D G and N G on consecutive
    cycles (period 3), the last N G last; two cycles after the last load the denormalising
    shift with rounding (registered), then saturation and sign: ``q_next`` is the result in
    that cycle (``LATENCY``, forwarded) and ``q``, ``div_zero``, ``overflow`` hold it from the
    next cycle until the next result. Every step is enabled by a registered one-hot control
    word (:class:`Control`).
    """

    @classmethod
    def check_parameters(cls, n: int, frac: int, iterations: int, seed_bits: int) -> None:
        """The filter's own parameter checks (ValueError naming the field): n in [8, 32],
        frac in [1, n - 2], iterations in [1, 4], seed_bits in [0, min(8, n - 1)]."""
        from navgate.systems.kf2x2.model import KfParams

        KfParams(n=n, frac=frac, div_iterations=iterations, div_seed_bits=seed_bits)

    def __init__(self, n: int = 20, frac: int = 10, iterations: int = 1, seed_bits: int = 8):
        self.n, self.frac, self.iterations, self.seed_bits = n, frac, iterations, seed_bits
        self.F = n
        self.offsets, self.LATENCY = divider_plan(iterations)
        rw = self.F + 2
        super().__init__({
            "start": In(1), "d": In(signed(n)),
            "q": Out(signed(n)), "q_next": Out(signed(n)),
            "div_zero": Out(1), "overflow": Out(1),
            "mul_a": Out(unsigned(self.F + 1)), "mul_b": Out(unsigned(self.F + 1)),
            "mul_load": Out(1),
            "mul_p": In(unsigned(rw)),
        })

    def elaborate(self, platform):
        m = Module()
        w, F, frac, k = self.n, self.F, self.frac, self.iterations
        rw = F + 2
        L = self.LATENCY
        ctl = Control(m, self.start, L + 1, "gs")
        d_reg = Signal(signed(w), reset_less=True)
        with m.If(self.start):
            m.d.sync += d_reg.eq(self.d)
        neg = Signal()
        zero = Signal()
        sh = Signal(signed(max(F + w + 2, 2 * w + 2).bit_length() + 1))
        Dn = Signal(unsigned(F))
        N = Signal(unsigned(rw))
        D = Signal(unsigned(rw))
        G = Signal(unsigned(rw))
        # s1: sign/magnitude and normalisation (model: a = |d|, D = a << (F-1-p))
        d = d_reg
        d_zero = d == 0
        a = Mux(d_zero, 1, Mux(d[-1], -d, d))[:w]
        pd, lzd = leading_one(m, a, "kf_pd")
        with m.If(ctl.at({1})):
            m.d.sync += [neg.eq(d[-1]), zero.eq(d_zero), sh.eq(2 * frac - pd - 1 - F),
                         Dn.eq((a << lzd)[:w] << (F - w))]
        # s2: seed from the ROM, first multiply D x0
        rom = Array(Const(int(v), unsigned(F + 1))
                    for v in goldschmidt_seed_table(self.seed_bits, F))
        index = Dn[F - 1 - self.seed_bits: F - 1] if self.seed_bits else 0
        seed = Signal(unsigned(F + 1))
        m.d.comb += seed.eq(rom[index])
        two = Const(2 << F, unsigned(rw + 1))
        g_now = Signal(unsigned(rw))
        m.d.comb += g_now.eq((two - self.mul_p)[:rw])
        loads: list[tuple[int, object, object]] = [(2, Dn, seed)]
        with m.If(ctl.at({2})):
            m.d.sync += N.eq(seed)
        if k == 1:
            loads.append((4, N, g_now))
        else:
            with m.If(ctl.at({4})):
                m.d.sync += [D.eq(self.mul_p), G.eq(g_now)]
            for i in range(k - 1):
                t0 = 5 + 3 * i
                loads += [(t0, D, G), (t0 + 1, N, G)]
                with m.If(ctl.at({t0 + 2})):
                    m.d.sync += [D.eq(self.mul_p), G.eq(g_now)]
                with m.If(ctl.at({t0 + 3})):
                    m.d.sync += N.eq(self.mul_p)
            loads.append((self.offsets[-1], N, G))
        assert [t for t, _, _ in loads] == self.offsets
        acc_a = acc_b = 0
        for t, va, vb in loads:
            sel = ctl.at({t})
            acc_a = acc_a | Mux(sel, va, 0)
            acc_b = acc_b | Mux(sel, vb, 0)
        m.d.comb += [self.mul_a.eq(acc_a), self.mul_b.eq(acc_b),
                     self.mul_load.eq(ctl.at(self.offsets))]
        # L-1: denormalising shift and rounding of the last product (as
        # navgate.gateware.goldschmidt); the result is registered with what saturation and
        # sign need (its negation, its top bit, whether the bits below are non-zero), so
        # that the forwarded result is a few LUTs behind registers
        n_last = self.mul_p
        q_low = Signal(unsigned(w))
        q_neg = Signal(unsigned(w))
        big = Signal()
        top = Signal()
        rest = Signal()
        left_amt = Signal(range(w + 1))
        right_m1 = Signal(range(max(2, F + w + 3)))
        m.d.comb += [left_amt.eq(Mux(sh[-1], 0, sh)), right_m1.eq(Mux(sh[-1], -sh - 1, 0))]
        left = n_last << left_amt
        right = ((n_last >> right_m1) + 1) >> 1
        shifted = Signal(unsigned(F + w + 3))
        m.d.comb += shifted.eq(Mux(sh[-1], right, left))
        with m.If(ctl.at({L - 1})):
            m.d.sync += [q_low.eq(shifted[:w]), q_neg.eq(-shifted[:w]),
                         big.eq(shifted[w:].any()), top.eq(shifted[w - 1]),
                         rest.eq(shifted[:w - 1].any())]
        # L: saturation, sign, divide-by-zero override (forwarded as q_next).
        # q_low > limit, limit = 2**(w-1) - 1 (positive) or 2**(w-1) (negative)
        over = big | (top & (~neg | rest))
        max_pos = (1 << (w - 1)) - 1
        min_neg = 1 << (w - 1)  # -2**(w-1) as a w-bit pattern
        value = Signal(unsigned(w))
        m.d.comb += value.eq(Mux(over, Mux(neg, min_neg, max_pos), Mux(neg, q_neg, q_low)))
        m.d.comb += self.q_next.eq(Mux(zero, max_pos, value.as_signed()))
        with m.If(ctl.at({L})):
            m.d.sync += [self.q.eq(self.q_next), self.overflow.eq(over & ~zero),
                         self.div_zero.eq(zero)]
        return m
