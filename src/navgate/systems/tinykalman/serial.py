"""Seed 001 TinyKalman, the SERIAL chip (``tinykalman_serial_top``): one bit-serial CORDIC
vectoring unit time-shared between roll and pitch, bit-exact to
:mod:`navgate.systems.tinykalman.model` (issue 30: fit one TinyTapeout IHP SG13G2 tile).

Reference: seed 001 ("Angle Estimation (CORDIC)"); :mod:`navgate.numerics.cordic` (the
vectoring datapath step for step: pre-rotation by +-90 deg, ``x' = x + d (y >>> i)``,
``y' = y - d (x >>> i)``, ``z' = z + d T[i]``, ``d = +1`` when y >= 0); R. Andraka, "A survey
of CORDIC algorithms for FPGA based computers", FPGA '98, section "bit-serial" (one full adder
per register, the shifted operand read from a tap of the circulating shift register).

Bit-serial arithmetic (:class:`TinyKalmanSerialCordic`): the x and y registers are
``W = 18``-bit (16-bit inputs, no guard bits, 2 growth bits: the model's register width)
shift registers that rotate right one bit per clock; z is a 16-bit shift register that moves
during the first 16 clocks of each pass. One pass is ``W`` clocks; in clock ``k`` of pass
``i`` the old bit ``k`` of each register sits at position 0 and the old bit ``k + i`` at
position ``i`` (the new bits enter at the top), so ``y >>> i`` is read by a tap multiplexer
indexed by the iteration counter (no barrel shifter), and by the captured sign bit once
``k + i >= W`` (the arithmetic shift's sign extension). Each register has one full adder and
a carry flip-flop; subtraction is ``a + ~b + 1`` (carry preset to 1). The signs of x and y at
the start of a pass are captured from the last sum bit of the previous pass (or at load).
Pass 0 is the pre-rotation (``x, y <- y, -x`` or ``-y, x`` when x < 0, the identity
otherwise: a negation is the same serial adder with a = 0); passes 1..16 are the 16
iterations; the angle table bit ``T[i]`` bit ``k`` comes from a constant lookup on
``(i, k)``.

Schedule per sample: the roll vector ``(az >>> 1, ay >>> 1)`` (17 passes), then the pitch
vector ``(min(mag, 32767), -((ax>>>1) + (ax>>>2) + (ax>>>4)))`` (17 passes), then the
output: ``LATENCY = 2 * 17 * 18 + 1 = 613`` clocks from the accepted input to the valid
output (measured in the tests). The stream interface is the parallel
:class:`~navgate.systems.tinykalman.datapath.TinyKalmanCordic`'s, less ``mag`` (the chip does
not use it): input ``{ax, ay, az}``, output ``{roll, pitch, sat}``.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth import Array, Cat, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, enum, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.numerics.cordic import atan_table
from navgate.systems.tinykalman.model import ANGLE_BITS, ITERATIONS, WIDTH

__all__ = ["TinyKalmanSerialCordic", "SERIAL_CORDIC_LATENCY", "REG_WIDTH", "PASSES"]

REG_WIDTH = WIDTH + 2  #: the model's vectoring register width (no guard bits)
PASSES = ITERATIONS + 1  #: pre-rotation + iterations
SERIAL_CORDIC_LATENCY = 2 * PASSES * REG_WIDTH + 1

SERIAL_ANGLES_IN = data.StructLayout({"ax": signed(16), "ay": signed(16), "az": signed(16)})
SERIAL_ANGLES_OUT = data.StructLayout({"roll": signed(16), "pitch": signed(16),
                                       "sat": unsigned(1)})


class _Phase(enum.Enum, shape=2):
    IDLE = 0
    ROLL = 1
    PITCH = 2
    OUT = 3


def _serial_add(a, b, sub, carry):
    """One bit of ``a + (sub ? ~b : b) + carry``: (sum, carry out) expressions."""
    bb = b ^ sub
    s = a ^ bb ^ carry
    c = (a & bb) | (a & carry) | (bb & carry)
    return s, c


class TinyKalmanSerialCordic(wiring.Component):
    """Roll and pitch from accelerometer words through one bit-serial CORDIC used twice."""

    LATENCY = SERIAL_CORDIC_LATENCY
    THROUGHPUT = Fraction(1, SERIAL_CORDIC_LATENCY + 1)

    def __init__(self, held_input: bool = False):
        #: ``held_input``: the producer holds ``i.payload`` from the handshake until the output
        #: is taken (the chip's SPI master does: its word register changes only during the next
        #: burst, a sample period later); ax is then read again for the pitch pass instead of
        #: being kept in a 16-bit register. False (default): any stream producer.
        self.held_input = held_input
        super().__init__({
            "i": In(stream.Signature(SERIAL_ANGLES_IN)),
            "o": Out(stream.Signature(SERIAL_ANGLES_OUT)),
        })

    def elaborate(self, platform):
        m = Module()
        W, ab = REG_WIDTH, ANGLE_BITS
        table = [int(t) & ((1 << ab) - 1) for t in atan_table(ITERATIONS, ab)]

        phase = Signal(_Phase)
        x = Signal(W)
        y = Signal(W)
        z = Signal(ab)
        cx, cy, cz = Signal(), Signal(), Signal()
        sx, sy = Signal(), Signal()  # signs of x and y at the start of the pass
        k = Signal(range(W))  # bit within the pass
        p = Signal(range(PASSES))  # 0: pre-rotation, 1..16: iteration p - 1
        if self.held_input:
            ax_in = self.i.payload.ax
            ax_neg = Signal(signed(16))
            m.d.comb += ax_neg.eq(-((ax_in >> 1) + (ax_in >> 2) + (ax_in >> 4)))
        else:
            ax_neg = Signal(signed(16))
        roll = Signal(signed(ab))
        sat = Signal()

        first = k == 0
        last_bit = k == W - 1
        last_pass = p == PASSES - 1
        it = Signal(range(ITERATIONS))
        m.d.comb += it.eq(p - 1)

        # taps: old bit k + i of the other register (position i), sign beyond the top
        beyond = (k + it) >= W
        tap_y = Mux(beyond, sy, y.bit_select(it, 1))
        tap_x = Mux(beyond, sx, x.bit_select(it, 1))
        tbit = Array(Const(t, ab) for t in table)[it].bit_select(k[:4], 1)

        # per-pass operands: (a, b, sub) for x and y, (b, sub) for z
        xa, xb, xs = Signal(), Signal(), Signal()
        ya, yb, ys = Signal(), Signal(), Signal()
        pos = ~sy  # d = +1 when y >= 0
        with m.If(p == 0):
            # pre-rotation: x < 0 and y >= 0: (y, -x); x < 0 and y < 0: (-y, x); else identity
            with m.If(sx):
                m.d.comb += [xa.eq(0), xb.eq(y[0]), xs.eq(sy),
                             ya.eq(0), yb.eq(x[0]), ys.eq(~sy)]
            with m.Else():
                m.d.comb += [xa.eq(x[0]), xb.eq(0), xs.eq(0),
                             ya.eq(y[0]), yb.eq(0), ys.eq(0)]
        with m.Else():
            m.d.comb += [xa.eq(x[0]), xb.eq(tap_y), xs.eq(~pos),
                         ya.eq(y[0]), yb.eq(tap_x), ys.eq(pos)]
        cin_x = Mux(first, xs, cx)
        cin_y = Mux(first, ys, cy)
        cin_z = Mux(first, ~pos, cz)
        sum_x, co_x = _serial_add(xa, xb, xs, cin_x)
        sum_y, co_y = _serial_add(ya, yb, ys, cin_y)
        sum_z, co_z = _serial_add(z[0], tbit, ~pos, cin_z)

        busy = (phase == _Phase.ROLL) | (phase == _Phase.PITCH)
        m.d.comb += [
            self.i.ready.eq(phase == _Phase.IDLE),
            self.o.valid.eq(phase == _Phase.OUT),
            self.o.payload.roll.eq(roll),
            self.o.payload.pitch.eq(z),
            self.o.payload.sat.eq(sat),
        ]

        def load(xv, yv):
            """Parallel load of a new vector (16-bit signed values, sign-extended)."""
            return [x.eq(xv.as_signed()), y.eq(yv.as_signed()),
                    sx.eq(xv.as_signed() < 0), sy.eq(yv.as_signed() < 0),
                    k.eq(0), p.eq(0)]

        with m.If(busy):
            m.d.sync += [x.eq(Cat(x[1:], sum_x)), y.eq(Cat(y[1:], sum_y)),
                         cx.eq(co_x), cy.eq(co_y), k.eq(k + 1)]
            with m.If((p != 0) & (k < ab)):
                m.d.sync += [z.eq(Cat(z[1:], sum_z)), cz.eq(co_z)]
            with m.If(p == 0):
                # z0 = +-90 deg after a pre-rotation, else 0 (z is loaded, not shifted)
                m.d.sync += z.eq(Mux(sx, Mux(sy, -(1 << (ab - 2)), 1 << (ab - 2)), 0))
            with m.If(last_bit):
                m.d.sync += [k.eq(0), p.eq(p + 1), sx.eq(sum_x), sy.eq(sum_y)]
                with m.If(last_pass):
                    with m.If(phase == _Phase.ROLL):
                        # x (>= 0) is the magnitude K |(x, y)|: saturate it to 16 bits
                        mag = Cat(x[1:], sum_x)
                        over = mag > 32767
                        m.d.sync += [roll.eq(z), sat.eq(over),
                                     phase.eq(_Phase.PITCH)]
                        m.d.sync += load(Mux(over, Const(32767, signed(16)), mag[:16]),
                                         ax_neg)
                    with m.Else():
                        m.d.sync += phase.eq(_Phase.OUT)
        with m.Switch(phase):
            with m.Case(_Phase.IDLE):
                with m.If(self.i.valid):
                    if not self.held_input:
                        ax = self.i.payload.ax
                        m.d.sync += ax_neg.eq(-((ax >> 1) + (ax >> 2) + (ax >> 4)))
                    m.d.sync += load(self.i.payload.az >> 1, self.i.payload.ay >> 1)
                    m.d.sync += phase.eq(_Phase.ROLL)
            with m.Case(_Phase.OUT):
                with m.If(self.o.ready):
                    m.d.sync += phase.eq(_Phase.IDLE)
        return m
