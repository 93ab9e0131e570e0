"""Pipelined float32 square root: radix-2 restoring digit recurrence, unrolled.

Implements ``navgate.numerics.fp32.fp32_sqrt`` bit for bit (correctly rounded,
flush-to-zero input, sqrt(-0) = -0, sqrt(negative nonzero) = QNAN;
docs/gateware-fp32.md).

Algorithm (Ercegovac & Lang, "Digital Arithmetic", 2004, ch. 6; the classic
bit-pair "digit-by-digit" integer square root): the exponent is made even by
doubling the significand when it is odd, so the radicand ``v`` lies in
[1, 4) and its root in [1, 2).  With ``N = v * 2**48`` (an integer), 25 root
bits (hidden bit, 23 fraction bits, round bit) are produced one per pipeline
stage: bring down the next bit pair, ``rem = 4*rem + pair``; if
``rem >= 4*root + 1`` subtract it and append a 1, else append a 0.  The final
remainder is non-zero exactly when the root has a non-zero tail, giving the
sticky bit for round-to-nearest-even.

Latency 29 cycles (1 unpack + 25 recurrence + 1 sticky + 2 round), one result
per cycle. ``steps_per_stage = s > 1`` chains ``s`` recurrence steps between registers
(latency ``4 + ceil(25 / s)``), as :class:`~navgate.gateware.fp32.div.Fp32Div`.
"""

import math

from amaranth.hdl import C, Cat, Module, Signal, signed, unsigned
from amaranth.lib import data

from navgate.gateware.parameters import CheckedParameters

from ._common import Pipe, StreamOp, _wire, finish_recurrence, unpack

__all__ = ["Fp32Sqrt"]


class Fp32Sqrt(CheckedParameters, StreamOp):
    """Float32 square root ``r = sqrt(a)``; input ``{a}``, output ``{r}``."""

    ROOT_BITS = 25
    LATENCY = ROOT_BITS + 4
    THROUGHPUT = 1.0
    IN_LAYOUT = data.StructLayout({"a": unsigned(32)})
    OUT_LAYOUT = data.StructLayout({"r": unsigned(32)})

    @classmethod
    def check_parameters(cls, steps_per_stage):
        if not isinstance(steps_per_stage, int) or not 1 <= steps_per_stage <= 25:
            raise ValueError(f"steps_per_stage must be in [1, 25], got {steps_per_stage!r}")

    @classmethod
    def latency_for(cls, steps_per_stage: int) -> int:
        """``LATENCY`` of a unit built with ``steps_per_stage`` (equal to the class's for 1)."""
        return 4 + math.ceil(cls.ROOT_BITS / steps_per_stage)

    def __init__(self, steps_per_stage: int = 1):
        self.steps_per_stage = steps_per_stage
        self.LATENCY = self.latency_for(steps_per_stage)
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        p = Pipe(m, self.i, self.o, self.LATENCY)

        # ---- stage 1: unpack, even exponent ---------------------------------------
        a = unpack(m, self.i.payload.a, "a")
        nan = a.nan | (a.sign & ~a.zero)
        inf = a.inf
        zero = a.zero
        odd = ~a.exp[0]  # unbiased exponent ea - 127 is odd when ea is even
        e_unb = Signal(signed(10))
        m.d.comb += e_unb.eq(a.exp - 127)
        exp = Signal(signed(10))
        m.d.comb += exp.eq((e_unb >> 1) + 127)
        # Radicand bits N = v * 2**48 = m_adj * 2**25, m_adj = mant << odd (25 bits);
        # its bit pairs from the top are m_adj[23:25], m_adj[21:23], ..., {m_adj[0], 0},
        # then zeros.  Pad one zero below m_adj so the pairs align: 26 bits, 13 pairs.
        rest = p.reg(Cat(C(0, 1), a.mant << odd), "s1_rest", unsigned(26))
        e = p.reg(exp, "s1_exp")
        s = p.reg(a.sign, "s1_sign")
        kind = p.reg(Cat(nan, inf, zero), "s1_kind")
        rem = C(0, 1)
        root = C(0, 1)

        # ---- stages 2..26: one root bit per stage -----------------------------------------
        for k in range(self.ROOT_BITS):
            keep = k == self.ROOT_BITS - 1 or (k + 1) % self.steps_per_stage == 0
            reg = p.reg if keep else _wire(m)
            if len(rest) >= 2:
                pair = rest[-2:]
                rest_next = rest[:-2]
            else:
                pair = C(0, 2)
                rest_next = None
            rem2 = Cat(pair, rem)                       # 4*rem + pair
            trial = Cat(C(1, 2), root)                  # 4*root + 1
            w = max(len(rem2), len(trial)) + 1
            diff = Signal(w, name=f"r{k}_diff")
            m.d.comb += diff.eq(rem2 - trial)
            bit = ~diff[w - 1]
            # rem <= 2*root holds after every step, so rem fits in len(root)+2 bits.
            rw = len(root) + 2
            nrem = Signal(rw, name=f"r{k}_rem")
            with m.If(bit):
                m.d.comb += nrem.eq(diff)
            with m.Else():
                m.d.comb += nrem.eq(rem2)
            root = reg(Cat(bit, root) if k else bit, f"r{k}_root")
            rem = reg(nrem, f"r{k}_remr")
            if rest_next is not None and len(rest_next):
                rest = reg(rest_next, f"r{k}_rest")
            else:
                rest = C(0, 0)
            e = reg(e, f"r{k}_exp", reset=True)
            s = reg(s, f"r{k}_sign", reset=True)
            kind = reg(kind, f"r{k}_kind", reset=True)

        # ---- sticky stage, round (a root never overflows or underflows), pack ------------
        finish_recurrence(m, p, root, rem, e, s, kind, self.o.payload.r)

        p.finish()
        return m
