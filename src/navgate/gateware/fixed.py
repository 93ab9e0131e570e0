"""Fixed-point multiplier gateware and the stream-pipeline helper shared by the fixed cores.

Reference: seed 004 (2x2 fixed-point Kalman filter, ``fxp_mul.v``): a parametric signed
Q(N, FRAC) multiplier (default N=20, FRAC=10) with a full-precision output (the 2N-bit
product, 2*FRAC fraction bits) and a truncated output (the product shifted right by FRAC,
"keeping the middle, aligned bits"). The bit-true model is
:mod:`navgate.numerics.fixed`: :func:`~navgate.numerics.fixed.fixed_mul_full` and
:func:`~navgate.numerics.fixed.fixed_mul_trunc` (``mode="wrap"`` and ``mode="saturate"``,
rounding by arithmetic shift = floor). :class:`FixedMul` gives all of them at once:

========== ======================= ==================================================
field      shape                   model
========== ======================= ==================================================
full       signed(2*width)         ``fixed_mul_full(a, b, QFormat(width, frac))``
trunc      signed(width)           ``fixed_mul_trunc(a, b, fmt, mode="wrap")[0]``
sat        signed(width)           ``fixed_mul_trunc(a, b, fmt, mode="saturate")[0]``
overflow   unsigned(1)             ``fixed_mul_trunc(a, b, fmt)[1]`` (same for both modes)
========== ======================= ==================================================

Pipelining (``LATENCY = 3``, ``THROUGHPUT = 1``): operand registers, product register,
result register, which is the register placement a DSP48E1 absorbs (AREG/BREG, MREG, PREG).
All stages advance together under one enable, ``~o.valid | o.ready`` (see
:class:`StreamPipeline`), so backpressure stalls the whole pipe and bubbles are squeezed
out at the output.
"""

from __future__ import annotations

from amaranth import Module, Signal, signed, unsigned
from amaranth.hdl import Mux, Value
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.parameters import CheckedParameters

__all__ = ["FixedMul", "StreamPipeline", "saturate_value"]


class StreamPipeline:
    """Valid bits and a common enable for a ``depth``-stage stream pipeline.

    ``en = ~o.valid | o.ready``: every stage register loads when ``en`` is high; the input is
    accepted (``i.ready = en``) exactly when the pipe moves, and ``o.valid`` is the valid bit
    of the last stage. ``o.valid`` is a register (never depends on ``o.ready``), and a valid
    output holds its payload until taken, as ``lib.stream`` requires. Data registers are
    created ``reset_less`` by :meth:`reg`: only the valid bits are reset.
    """

    def __init__(self, m: Module, i: stream.Interface, o: stream.Interface, depth: int):
        if depth < 1:
            raise ValueError("a pipeline needs at least one stage")
        self.en = Signal(name="pipe_en")
        self.valid = [Signal(name=f"pipe_valid_{k}") for k in range(depth)]
        m.d.comb += [self.en.eq(~o.valid | o.ready), i.ready.eq(self.en),
                     o.valid.eq(self.valid[-1])]
        with m.If(self.en):
            m.d.sync += self.valid[0].eq(i.valid)
            for k in range(1, depth):
                m.d.sync += self.valid[k].eq(self.valid[k - 1])

    @staticmethod
    def reg(shape, name: str) -> Signal:
        """A data register (no reset: only the valid bits need one)."""
        return Signal(shape, name=name, reset_less=True)


def saturate_value(value: Value, width: int) -> tuple[Value, Value]:
    """Clamp signed ``value`` to ``signed(width)``: ``(clamped, overflow)`` expressions."""
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    over_hi = value > hi
    over_lo = value < lo
    result = Mux(over_hi, hi, Mux(over_lo, lo, value[:width].as_signed()))
    return result[:width].as_signed(), over_hi | over_lo


class FixedMul(CheckedParameters, wiring.Component):
    """Signed Q(width, frac) multiplier: full product, truncated and saturated results,
    overflow flag (seed 004 fxp_mul)."""

    LATENCY = 3
    THROUGHPUT = 1

    @classmethod
    def check_parameters(cls, width, frac):
        if not 2 <= width <= 64:
            raise ValueError(f"width must be in [2, 64], got {width}")
        if not 0 <= frac <= 2 * width:
            raise ValueError(f"frac must be in [0, 2*width], got {frac}")

    def __init__(self, width: int = 20, frac: int = 10):
        self.width = width
        self.frac = frac
        super().__init__({
            "i": In(stream.Signature(data.StructLayout({
                "a": signed(width), "b": signed(width)}))),
            "o": Out(stream.Signature(data.StructLayout({
                "full": signed(2 * width),
                "trunc": signed(width),
                "sat": signed(width),
                "overflow": unsigned(1),
            }))),
        })

    def elaborate(self, platform):
        m = Module()
        w, f = self.width, self.frac
        pipe = StreamPipeline(m, self.i, self.o, self.LATENCY)
        a = pipe.reg(signed(w), "a_q")
        b = pipe.reg(signed(w), "b_q")
        p = pipe.reg(signed(2 * w), "p_q")
        out = pipe.reg(self.o.payload.shape(), "out_q")
        # product >> frac (floor); 2w bits always hold it (|a*b| <= 2**(2w-2))
        shifted = p >> f
        sat, over = saturate_value(shifted, w)
        with m.If(pipe.en):
            m.d.sync += [
                a.eq(self.i.payload.a),
                b.eq(self.i.payload.b),
                p.eq(a * b),
                out.full.eq(p),
                out.trunc.eq(shifted[:w]),
                out.sat.eq(sat),
                out.overflow.eq(over),
            ]
        m.d.comb += self.o.payload.eq(out)
        return m
