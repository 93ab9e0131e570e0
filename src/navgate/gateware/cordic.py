"""CORDIC gateware: vectoring (atan2 and magnitude) and rotation (cos and sin).

Implements :mod:`navgate.numerics.cordic` bit for bit (``cordic_vectoring``,
``cordic_rotation``); the datapath, step for step, is the one written in that module's
docstring, and the arctangent table is taken from its ``atan_table`` so the two cannot
drift apart. References: Volder 1959; Andraka, "A survey of CORDIC algorithms for FPGA
based computers", FPGA '98 (the unrolled and the iterative, bit-serial-free architectures
below are his figures 2 and 3). Seed 001 computes roll and pitch with a vectoring CORDIC and
16-bit angles (32768 = 180 deg); the defaults here follow it.

Cores
-----
:class:`CordicAtan2` (unrolled, pipelined)
    One register stage for the +-90 deg pre-rotation, one per iteration, and with
    ``compensate=True`` one more for the gain-compensation multiply.
    ``LATENCY = iterations + 1 (+1)``, ``THROUGHPUT = 1``.
:class:`CordicAtan2Iterative`
    One set of x/y/z registers, a variable arithmetic shifter and a small arctangent ROM
    indexed by the iteration counter. An input is accepted while the core is idle or in the
    cycle its previous result is written out, so ``THROUGHPUT = 1/iterations`` and
    ``LATENCY = iterations + 1`` (the compensation multiply, if any, sits in the output path
    and adds no cycle).
:class:`CordicSinCos` (unrolled, pipelined)
    Quadrant fold into [-90, +90] deg, ``iterations`` stages from the gain-compensated start
    vector, negation for the folded quadrants. ``LATENCY = iterations + 1``,
    ``THROUGHPUT = 1``.

Payloads (``lib.data`` structs): vectoring ``{x, y}`` (signed ``width``) ->
``{magnitude, angle}`` (``magnitude`` unsigned ``width + 1`` bits uncompensated, ``width``
bits compensated: |(x, y)| <= sqrt(2) * 2**(width-1) < 2**width, times K < 1.65 without
compensation; ``angle`` signed ``angle_bits``); rotation ``{angle}`` -> ``{cos, sin}``
(signed ``width``, 1.0 = 2**(width-2)).

Register widths: x and y carry ``width + guard_bits + 2`` bits (sqrt(2) * K < 4, as the model
derives); the angle accumulator carries ``angle_bits`` bits and wraps, which equals the
model's wrap of the final sum because the wrap is a ring homomorphism. The rotation's x/y
registers carry ``width + guard_bits`` bits: the start vector is 2**(width-2+g)/K and never
grows past 2**(width-2+g) plus a few truncation LSBs.

Zero input: (0, 0) gives magnitude 0 and the meaningless angle sum(T), as the model; callers
gate it.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth import Array, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.fixed import StreamPipeline
from navgate.gateware.parameters import CheckedParameters
from navgate.numerics.cordic import atan_table, cordic_gain

__all__ = ["CordicAtan2", "CordicAtan2Iterative", "CordicSinCos"]


def _check(width: int, iterations: int, angle_bits: int, guard_bits: int) -> None:
    # the ranges the bit-true model accepts (navgate.numerics.cordic)
    if not 2 <= width <= 40:
        raise ValueError(f"width must be in [2, 40], got {width}")
    if not 1 <= iterations <= 40:
        raise ValueError(f"iterations must be in [1, 40], got {iterations}")
    if not 4 <= angle_bits <= 48:
        raise ValueError(f"angle_bits must be in [4, 48], got {angle_bits}")
    if not 0 <= guard_bits <= 16:
        raise ValueError(f"guard_bits must be in [0, 16], got {guard_bits}")


class _VectoringBase(CheckedParameters, wiring.Component):
    @classmethod
    def check_parameters(cls, width, iterations, angle_bits, guard_bits, compensate,
                         gain_frac_bits):
        _check(width, iterations, angle_bits, guard_bits)
        if compensate and gain_frac_bits is not None and int(gain_frac_bits) < 1:
            raise ValueError("gain_frac_bits must be >= 1")

    def __init__(self, width: int, iterations: int, angle_bits: int, guard_bits: int,
                 compensate: bool, gain_frac_bits: int | None):
        self.width = width
        self.iterations = iterations
        self.angle_bits = angle_bits
        self.guard_bits = guard_bits
        self.compensate = bool(compensate)
        self.gain_frac_bits = (width + 2) if gain_frac_bits is None else int(gain_frac_bits)
        self.table = [int(t) for t in atan_table(iterations, angle_bits)]
        self.kinv = round(2.0**self.gain_frac_bits / cordic_gain(iterations))
        #: internal x/y register width
        self.reg_width = width + guard_bits + 2
        mag_width = width if self.compensate else width + 1
        super().__init__({
            "i": In(stream.Signature(data.StructLayout({
                "x": signed(width), "y": signed(width)}))),
            "o": Out(stream.Signature(data.StructLayout({
                "magnitude": unsigned(mag_width), "angle": signed(angle_bits)}))),
        })

    def _prerotate(self, x, y):
        """Model's pre-rotation into the right half-plane: (x0, y0, z0) expressions."""
        g, ab = self.guard_bits, self.angle_bits
        xs = x.as_signed() << g
        ys = y.as_signed() << g
        left = xs < 0
        up = ys >= 0
        quarter = 1 << (ab - 2)
        x0 = Mux(left, Mux(up, ys, -ys), xs)
        y0 = Mux(left, Mux(up, -xs, xs), ys)
        z0 = Mux(left, Mux(up, quarter, -quarter), 0)
        return x0, y0, z0

    def _magnitude(self, x):
        """Output magnitude from the final x register value (expression)."""
        g = self.guard_bits
        if self.compensate:
            c = self.gain_frac_bits
            return (x * Const(self.kinv, unsigned(self.kinv.bit_length()))) >> (c + g)
        return x >> g


class CordicAtan2(_VectoringBase):
    """CORDIC vectoring atan2(y, x) and magnitude, unrolled: one result per cycle."""

    THROUGHPUT = 1

    def __init__(self, width: int = 16, iterations: int = 16, angle_bits: int = 16,
                 guard_bits: int = 4, compensate: bool = False,
                 gain_frac_bits: int | None = None):
        super().__init__(width, iterations, angle_bits, guard_bits, compensate, gain_frac_bits)
        self.LATENCY = iterations + 1 + (1 if self.compensate else 0)

    def elaborate(self, platform):
        m = Module()
        n, rw, ab = self.iterations, self.reg_width, self.angle_bits
        pipe = StreamPipeline(m, self.i, self.o, self.LATENCY)
        xs = [pipe.reg(signed(rw), f"x_{k}") for k in range(n + 1)]
        ys = [pipe.reg(signed(rw), f"y_{k}") for k in range(n + 1)]
        zs = [pipe.reg(signed(ab), f"z_{k}") for k in range(n + 1)]
        x0, y0, z0 = self._prerotate(self.i.payload.x, self.i.payload.y)
        with m.If(pipe.en):
            m.d.sync += [xs[0].eq(x0), ys[0].eq(y0), zs[0].eq(z0)]
            for k in range(n):
                x, y, z = xs[k], ys[k], zs[k]
                pos = ~y[-1]
                dx, dy = y >> k, x >> k
                m.d.sync += [
                    xs[k + 1].eq(Mux(pos, x + dx, x - dx)),
                    ys[k + 1].eq(Mux(pos, y - dy, y + dy)),
                    zs[k + 1].eq(Mux(pos, z + self.table[k], z - self.table[k])),
                ]
        if self.compensate:
            mag = pipe.reg(self.o.payload.magnitude.shape(), "mag_q")
            angle = pipe.reg(signed(ab), "angle_q")
            with m.If(pipe.en):
                m.d.sync += [mag.eq(self._magnitude(xs[n])), angle.eq(zs[n])]
            m.d.comb += [self.o.payload.magnitude.eq(mag), self.o.payload.angle.eq(angle)]
        else:
            m.d.comb += [self.o.payload.magnitude.eq(self._magnitude(xs[n])),
                         self.o.payload.angle.eq(zs[n])]
        return m


class CordicAtan2Iterative(_VectoringBase):
    """CORDIC vectoring atan2(y, x) and magnitude, iterative: one result per ``iterations``
    cycles from one adder set."""

    def __init__(self, width: int = 16, iterations: int = 16, angle_bits: int = 16,
                 guard_bits: int = 4, compensate: bool = False,
                 gain_frac_bits: int | None = None):
        super().__init__(width, iterations, angle_bits, guard_bits, compensate, gain_frac_bits)
        self.LATENCY = iterations + 1
        self.THROUGHPUT = Fraction(1, iterations)

    def elaborate(self, platform):
        m = Module()
        n, rw, ab = self.iterations, self.reg_width, self.angle_bits
        x = Signal(signed(rw), reset_less=True)
        y = Signal(signed(rw), reset_less=True)
        z = Signal(signed(ab), reset_less=True)
        count = Signal(range(n), reset_less=True)
        busy = Signal()
        out = Signal(self.o.payload.shape(), reset_less=True)
        out_valid = Signal()

        table = Array(Const(t, signed(ab)) for t in self.table)
        pos = ~y[-1]
        dx = Signal(signed(rw))
        dy = Signal(signed(rw))
        t = Signal(signed(ab))
        m.d.comb += [dx.eq(y >> count), dy.eq(x >> count), t.eq(table[count])]
        x_next = Mux(pos, x + dx, x - dx)
        y_next = Mux(pos, y - dy, y + dy)
        z_next = Mux(pos, z + t, z - t)

        last = count == n - 1
        out_free = ~out_valid | self.o.ready
        finish = busy & last & out_free
        accept = self.i.valid & self.i.ready
        m.d.comb += [
            self.i.ready.eq(~busy | finish),
            self.o.valid.eq(out_valid),
            self.o.payload.eq(out),
        ]
        with m.If(self.o.ready):
            m.d.sync += out_valid.eq(0)
        with m.If(finish):
            m.d.sync += [
                out.magnitude.eq(self._magnitude(x_next)),
                out.angle.eq(z_next),
                out_valid.eq(1),
                busy.eq(0),
            ]
        with m.Elif(busy & ~last):
            m.d.sync += [x.eq(x_next), y.eq(y_next), z.eq(z_next), count.eq(count + 1)]
        with m.If(accept):
            x0, y0, z0 = self._prerotate(self.i.payload.x, self.i.payload.y)
            m.d.sync += [x.eq(x0), y.eq(y0), z.eq(z0), count.eq(0), busy.eq(1)]
        return m


class CordicSinCos(CheckedParameters, wiring.Component):
    """CORDIC rotation: cos and sin of a binary angle, unrolled: one result per cycle."""

    THROUGHPUT = 1

    @classmethod
    def check_parameters(cls, width, iterations, angle_bits, guard_bits):
        _check(width, iterations, angle_bits, guard_bits)
        if width < 4:
            raise ValueError("rotation needs width >= 4")

    def __init__(self, width: int = 16, iterations: int = 16, angle_bits: int = 16,
                 guard_bits: int = 4):
        self.width = width
        self.iterations = iterations
        self.angle_bits = angle_bits
        self.guard_bits = guard_bits
        self.table = [int(t) for t in atan_table(iterations, angle_bits)]
        self.x0 = round(2.0 ** (width - 2 + guard_bits) / cordic_gain(iterations))
        self.reg_width = width + guard_bits
        self.LATENCY = iterations + 1
        super().__init__({
            "i": In(stream.Signature(data.StructLayout({"angle": signed(angle_bits)}))),
            "o": Out(stream.Signature(data.StructLayout({
                "cos": signed(width), "sin": signed(width)}))),
        })

    def elaborate(self, platform):
        m = Module()
        n, rw, ab, g = self.iterations, self.reg_width, self.angle_bits, self.guard_bits
        pipe = StreamPipeline(m, self.i, self.o, self.LATENCY)
        xs = [pipe.reg(signed(rw), f"x_{k}") for k in range(n + 1)]
        ys = [pipe.reg(signed(rw), f"y_{k}") for k in range(n + 1)]
        # |z| <= 90 deg after the fold and shrinks from there: angle_bits - 1 bits hold it
        zs = [pipe.reg(signed(ab), f"z_{k}") for k in range(n + 1)]
        flips = [pipe.reg(unsigned(1), f"flip_{k}") for k in range(n + 1)]
        quarter, half = 1 << (ab - 2), 1 << (ab - 1)
        a = self.i.payload.angle
        hi, lo = a > quarter, a < -quarter
        with m.If(pipe.en):
            m.d.sync += [
                xs[0].eq(self.x0),
                ys[0].eq(0),
                zs[0].eq(Mux(hi, a - half, Mux(lo, a + half, a))),
                flips[0].eq(hi | lo),
            ]
            for k in range(n):
                x, y, z = xs[k], ys[k], zs[k]
                pos = ~z[-1]
                dx, dy = y >> k, x >> k
                m.d.sync += [
                    xs[k + 1].eq(Mux(pos, x - dx, x + dx)),
                    ys[k + 1].eq(Mux(pos, y + dy, y - dy)),
                    zs[k + 1].eq(Mux(pos, z - self.table[k], z + self.table[k])),
                    flips[k + 1].eq(flips[k]),
                ]
        # negate (exactly, in rw + 1 bits), then floor by the guard bits, as the model
        x_out = Mux(flips[n], -xs[n], xs[n]) >> g
        y_out = Mux(flips[n], -ys[n], ys[n]) >> g
        m.d.comb += [self.o.payload.cos.eq(x_out), self.o.payload.sin.eq(y_out)]
        return m
