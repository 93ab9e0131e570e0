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

Latency 30 cycles (1 unpack + 1 pre-normalise + 25 recurrence + 1 sticky + 2
round), one result per cycle. ``steps_per_stage = s > 1`` chains ``s`` recurrence steps
between registers (latency ``5 + ceil(25 / s)``; the same arithmetic, a longer path per
stage): seed 003's attitude circuit uses ``s = 2`` to shorten its dependency chain.
"""

import math

from amaranth.hdl import Cat, Module, Signal, signed, unsigned
from amaranth.lib import data

from navgate.gateware.parameters import CheckedParameters

from ._common import Pipe, StreamOp, _wire, finish_recurrence, unpack

__all__ = ["Fp32Div"]


class Fp32Div(CheckedParameters, StreamOp):
    """Float32 divide ``r = a / b``; input ``{a, b}``, output ``{r}``."""

    QUOTIENT_BITS = 25
    LATENCY = QUOTIENT_BITS + 5
    THROUGHPUT = 1.0
    IN_LAYOUT = data.StructLayout({"a": unsigned(32), "b": unsigned(32)})
    OUT_LAYOUT = data.StructLayout({"r": unsigned(32)})

    @classmethod
    def check_parameters(cls, steps_per_stage):
        if not isinstance(steps_per_stage, int) or not 1 <= steps_per_stage <= 25:
            raise ValueError(f"steps_per_stage must be in [1, 25], got {steps_per_stage!r}")

    @classmethod
    def latency_for(cls, steps_per_stage: int) -> int:
        """``LATENCY`` of a unit built with ``steps_per_stage`` (equal to the class's for 1)."""
        return 5 + math.ceil(cls.QUOTIENT_BITS / steps_per_stage)

    def __init__(self, steps_per_stage: int = 1):
        self.steps_per_stage = steps_per_stage
        self.LATENCY = self.latency_for(steps_per_stage)
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        p = Pipe(m, self.i, self.o, self.LATENCY)

        # ---- stage 1: unpack, special cases ------------------------
        a = unpack(m, self.i.payload.a, "a")
        b = unpack(m, self.i.payload.b, "b")
        sign = a.sign ^ b.sign
        nan = a.nan | b.nan | (a.inf & b.inf) | (a.zero & b.zero)
        inf = a.inf | b.zero  # (nan has priority)
        zero = a.zero | b.inf
        exp = Signal(signed(10))
        m.d.comb += exp.eq(a.exp - b.exp + 127)  # the "- shift" follows in stage 3
        s0_ma = p.reg(a.mant, "s0_ma")
        s0_mb = p.reg(b.mant, "s0_mb")
        s0_e = p.reg(exp, "s0_exp", reset=True)
        s0_s = p.reg(sign, "s0_sign", reset=True)
        s0_kind = p.reg(Cat(nan, inf, zero), "s0_kind", reset=True)

        # ---- stage 2: pre-normalise the dividend --------------------------------------------
        shift = s0_ma < s0_mb
        r = p.reg(s0_ma << shift, "s1_r", unsigned(25))
        d = p.reg(s0_mb, "s1_d")
        s1_shift = p.reg(shift, "s1_shift")
        e = p.reg(s0_e, "s1_exp", reset=True)
        s = p.reg(s0_s, "s1_sign", reset=True)
        kind = p.reg(s0_kind, "s1_kind", reset=True)

        # ---- stages 3..27: one quotient bit per stage --------------------------------
        q = None
        for k in range(self.QUOTIENT_BITS):
            keep = k == self.QUOTIENT_BITS - 1 or (k + 1) % self.steps_per_stage == 0
            reg = p.reg if keep else _wire(m)
            diff = Signal(26, name=f"q{k}_diff")
            m.d.comb += diff.eq(r - d)
            bit = ~diff[25]  # r >= d
            nxt = Signal(25, name=f"q{k}_next")
            with m.If(bit):
                m.d.comb += nxt.eq(diff[0:24] << 1)
            with m.Else():
                m.d.comb += nxt.eq(r[0:24] << 1)
            q = reg(bit if q is None else Cat(bit, q), f"q{k}_q")
            r = reg(nxt, f"q{k}_r", unsigned(25))
            if k != self.QUOTIENT_BITS - 1:
                d = reg(d, f"q{k}_d")
            e = reg(e - s1_shift if k == 0 else e, f"q{k}_exp", signed(10), reset=True)
            s = reg(s, f"q{k}_sign", reset=True)
            kind = reg(kind, f"q{k}_kind", reset=True)

        # ---- sticky stage, round, range check, pack (q[24] == 1: quotient in [1, 2)) -----
        finish_recurrence(m, p, q, r, e, s, kind, self.o.payload.r)

        p.finish()
        return m
