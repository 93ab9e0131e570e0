"""Yardstick blocks: bare registered multiplies that every timing report measures beside the
designs, in the same run and the same flow.

A yardstick is ``operand registers -> one multiply -> product register``: the shortest
pipeline a single-cycle multiply can sit in. Its figures are the ceiling a design with a
single-cycle multiply of that size can reach on each timing model (xc7 logic-only ``sta``, the
ECP5 and Nexus routed proxies, docs/build-flow.md), so a design is judged against a number
measured with the same tools, the same seeds and the same load on the machine.

* ``mul_24x17``: unsigned 24 x 17 - the wider half of the float32 significand product split
  over two DSP48E1 (``fp32_mul``);
* ``mul_20x20``: signed 20 x 20 - the seed-004 Q(20, FRAC) multiply of ``kf2x2``;
* ``mul_24x24``: unsigned 24 x 24 - the whole float32 significand product in one cycle.

Interface: ``i`` a stream of ``{a, b}`` and ``o`` a stream of the full product. A yardstick has
no backpressure (no clock enable in the multiply path): ``i.ready`` is tied high and
``o.ready`` is ignored, so a consumer must take every result (a yardstick is a measuring
device, not a core to build with).
``LATENCY = 2`` (operand register, product register), ``THROUGHPUT = 1``.
"""

from __future__ import annotations

from amaranth import Module, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.parameters import CheckedParameters

__all__ = ["RegisteredMul", "mul_20x20", "mul_24x17", "mul_24x24"]


class RegisteredMul(CheckedParameters, wiring.Component):
    """Bare registered multiply: operand registers, one product, product register."""

    LATENCY = 2
    THROUGHPUT = 1

    @classmethod
    def check_parameters(cls, a_width, b_width, is_signed):
        if a_width < 1 or b_width < 1:
            raise ValueError("operand widths must be at least 1 bit")

    def __init__(self, a_width: int, b_width: int, is_signed: bool = False):
        self.a_width, self.b_width, self.is_signed = a_width, b_width, is_signed
        shape = signed if is_signed else unsigned
        self._a_shape, self._b_shape = shape(a_width), shape(b_width)
        self._p_shape = shape(a_width + b_width)
        layout = data.StructLayout({"a": self._a_shape, "b": self._b_shape})
        super().__init__({
            "i": In(stream.Signature(layout)),
            "o": Out(stream.Signature(self._p_shape)),
        })

    def elaborate(self, platform) -> Module:
        m = Module()
        a = Signal(self._a_shape, name="a_q", reset_less=True)
        b = Signal(self._b_shape, name="b_q", reset_less=True)
        p = Signal(self._p_shape, name="p_q", reset_less=True)
        valid = Signal(2, name="valid_q")
        m.d.sync += [
            a.eq(self.i.payload.a),
            b.eq(self.i.payload.b),
            p.eq(a * b),
            valid.eq(valid[:1] << 1 | self.i.valid),
        ]
        m.d.comb += [self.o.payload.eq(p), self.o.valid.eq(valid[1]), self.i.ready.eq(1)]
        return m


def mul_24x17() -> RegisteredMul:
    """Unsigned 24 x 17 registered multiply (fp32_mul's wider DSP half)."""
    return RegisteredMul(24, 17)


def mul_20x20() -> RegisteredMul:
    """Signed 20 x 20 registered multiply (the kf2x2 Q(20, FRAC) product)."""
    return RegisteredMul(20, 20, is_signed=True)


def mul_24x24() -> RegisteredMul:
    """Unsigned 24 x 24 registered multiply (a whole float32 significand product)."""
    return RegisteredMul(24, 24)
