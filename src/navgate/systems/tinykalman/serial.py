"""Seed 001 TinyKalman, the SERIAL chip (``tinykalman_serial_top``): one bit-serial CORDIC
vectoring unit time-shared between roll and pitch, and the steady-state filter run bit-serially
on the same adders, bit-exact to :mod:`navgate.systems.tinykalman.model`, small enough for one
TinyTapeout IHP SG13G2 1x1 tile.

Reference: seed 001 ("Angle Estimation (CORDIC)", "Sensor Fusion"); :mod:`navgate.numerics.cordic`
(the vectoring datapath step for step: pre-rotation by +-90 deg, ``x' = x + d (y >>> i)``,
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

Schedule per sample: the roll vector ``(az >>> 1, ay >>> 1)`` (17 passes); then x takes
``min(mag, 32767)`` and y is built as ``0 - (ax >>> 1) - (ax >>> 2) - (ax >>> 4)`` in three
passes of y's own adder (the model's ``-((ax>>>1) + (ax>>>2) + (ax>>>4))``: the same integer;
``(ax >>> s)`` bit k is ax bit ``min(k + s, 15)``, a tap of the held ax bits); then the pitch
vector (17 passes). ``LATENCY = (2 * 17 + 3) * 18 + 1 = 667`` clocks from the accepted input
to the valid output (measured in the tests). The stream interface is the parallel
:class:`~navgate.systems.tinykalman.datapath.TinyKalmanCordic`'s, less ``mag`` (the chip does
not use it): input ``{ax, ay, az}``, output ``{roll, pitch, sat}``.

:class:`TinyKalmanSerialDatapath` (the chip's arithmetic) adds the filter on z's adder, 16-clock
passes on 16-bit wrap-around words: the prediction ``state += rate >>> 6`` (rate bits 6..15 in
``z[:10]``, shifted arithmetically so that z[0] is bit ``min(k + 6, 15)`` in clock k), and after
each angle ``z = meas - state`` (the innovation, z held the measured angle) then
``state += z >>> 6`` (read at z[6] while z shifts arithmetically). The filter state registers
rotate through the adder and are the packet's bytes.

In the chip (``held_input=True, spi_fed=True``) the SPI master shifts az and ay straight into x
and y and the rates into ``z[:10]`` while the block is idle (x, y, z are free between samples);
each prediction runs as soon as its rate's last kept bit is in (16 clocks; the next word's
first bit comes 7 SCLK periods later, 28 clocks at the shortest ``spi_div = 2``); ax
and the WHO_AM_I flag are read from the master's held registers.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth import Array, Cat, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, enum, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.parameters import CheckedParameters
from navgate.nav import validate
from navgate.numerics.cordic import atan_table
from navgate.systems.tinykalman.datapath import DATAPATH_IN
from navgate.systems.tinykalman.model import ANGLE_BITS, ITERATIONS, WIDTH

__all__ = ["TinyKalmanSerialCordic", "TinyKalmanSerialDatapath", "SERIAL_CORDIC_LATENCY",
           "SERIAL_DATAPATH_LATENCY", "REG_WIDTH", "PASSES"]

REG_WIDTH = WIDTH + 2  #: the model's vectoring register width (no guard bits)
PASSES = ITERATIONS + 1  #: pre-rotation + iterations
AXN_PASSES = 3  #: y <- 0 - (ax >>> 1) - (ax >>> 2) - (ax >>> 4)
SERIAL_CORDIC_LATENCY = (2 * PASSES + AXN_PASSES) * REG_WIDTH + 1

SERIAL_ANGLES_IN = data.StructLayout({"ax": signed(16), "ay": signed(16), "az": signed(16)})
SERIAL_ANGLES_OUT = data.StructLayout({"roll": signed(16), "pitch": signed(16),
                                       "sat": unsigned(1)})
FILTER_PASS = ANGLE_BITS  #: clocks per filter pass (16-bit words)
#: the chip's data path (``spi_fed``): the predictions run during the burst, so the update is
#: two filter passes per axis after each angle; a stream producer: + the two predictions
SERIAL_DATAPATH_LATENCY = SERIAL_CORDIC_LATENCY + 2 * 2 * FILTER_PASS
SERIAL_DATAPATH_LATENCY_STREAM = SERIAL_DATAPATH_LATENCY + 2 * FILTER_PASS
SERIAL_DATAPATH_OUT = data.StructLayout({"roll": signed(16), "pitch": signed(16),
                                         "sat": unsigned(1), "ok": unsigned(1)})


class _Phase(enum.Enum, shape=4):
    IDLE = 0
    ROLL = 1
    PITCH = 2
    OUT = 3
    ROLL_F = 4  # the roll filter update (TinyKalmanSerialDatapath)
    PITCH_F = 5  # the pitch filter update
    AXN = 6  # y <- -((ax >>> 1) + (ax >>> 2) + (ax >>> 4)): three serial subtractions
    PRED_R = 7  # roll state <- roll state + (gx >>> 6), from the rate bits in z
    PRED_P = 8  # pitch state <- pitch state + (gy >>> 6)


def _serial_add(a, b, sub, carry):
    """One bit of ``a + (sub ? ~b : b) + carry``: (sum, carry out) expressions."""
    bb = b ^ sub
    s = a ^ bb ^ carry
    c = (a & bb) | (a & carry) | (bb & carry)
    return s, c


class TinyKalmanSerialCordic(CheckedParameters, wiring.Component):
    """Roll and pitch from accelerometer words through one bit-serial CORDIC used twice."""

    LATENCY = SERIAL_CORDIC_LATENCY
    THROUGHPUT = Fraction(1, SERIAL_CORDIC_LATENCY + 1)
    _FILTER = False

    @classmethod
    def check_parameters(cls, held_input, spi_fed):
        held_input = validate.flag(f"{cls.__name__}: held_input", held_input)
        spi_fed = validate.flag(f"{cls.__name__}: spi_fed", spi_fed)
        if spi_fed and not held_input:
            raise ValueError(f"{cls.__name__}: spi_fed needs held_input")

    def __init__(self, held_input: bool = False, spi_fed: bool = False):
        #: ``held_input``: the producer holds ``i.payload`` from the handshake until the output
        #: is taken (the chip's SPI master does: its word registers change only during the next
        #: burst, a sample period later); ax (and in the data path gx, gy, ok) are then read
        #: from it instead of being kept in registers here. False (default): any producer.
        self.held_input = held_input
        #: ``spi_fed`` (the serial chip): az and ay are not read from ``i.payload`` but shifted
        #: into x and y by the SPI master while the block is idle (``spi_bit``, ``shift_az``,
        #: ``shift_ay``: :class:`~navgate.systems.tinykalman.spi.Mpu6500Spi` with
        #: ``external=("ay", "az")``); x and y are free then, so the words need no register.
        self.spi_fed = spi_fed
        if self._FILTER and not spi_fed:
            self.LATENCY = SERIAL_DATAPATH_LATENCY_STREAM
            self.THROUGHPUT = Fraction(1, self.LATENCY + 1)
        sig = self._signature()
        if spi_fed:
            sig.update({"spi_bit": In(1), "shift_ay": In(1), "shift_az": In(1)})
            if self._FILTER:
                sig.update({"shift_gx": In(1), "shift_gy": In(1), "last_gx": In(1),
                            "last_gy": In(1)})
        super().__init__(sig)

    def _signature(self):
        return {"i": In(stream.Signature(SERIAL_ANGLES_IN)),
                "o": Out(stream.Signature(SERIAL_ANGLES_OUT))}

    def elaborate(self, platform):
        m = Module()
        W, ab = REG_WIDTH, ANGLE_BITS
        table = [int(t) & ((1 << ab) - 1) for t in atan_table(ITERATIONS, ab)]
        filt = self._FILTER
        inp = self.i.payload

        phase = Signal(_Phase)
        # written before they are read in every sample: no reset (docs: the register list)
        x = Signal(W, reset_less=True)
        y = Signal(W, reset_less=True)
        z = Signal(ab, reset_less=True)
        cx, cy, cz = (Signal(reset_less=True, name=n) for n in ("cx", "cy", "cz"))
        # signs of x and y at the start of the pass
        sx, sy = Signal(reset_less=True, name="sx"), Signal(reset_less=True, name="sy")
        k = Signal(range(W), reset_less=True)  # bit within the pass
        p = Signal(range(PASSES), reset_less=True)  # 0: pre-rotation, 1..16: iteration p - 1
        # ax bits 1..15 (the bits the pitch vector uses)
        ax_bits = Signal(WIDTH - 1, reset_less=not self.held_input)
        if self.held_input:
            m.d.comb += ax_bits.eq(inp.ax[1:])
        sat = Signal()

        first = k == 0
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
        sum_x, co_x = _serial_add(xa, xb, xs, cin_x)
        sum_y, co_y = _serial_add(ya, yb, ys, cin_y)

        # the third adder: z's angle accumulation, and in the data path the filter's passes
        za, zb, zs = Signal(), Signal(), Signal()
        m.d.comb += [za.eq(z[0]), zb.eq(tbit), zs.eq(~pos)]
        in_filter = Signal()
        if filt:
            roll_s = Signal(signed(ab))  # the filter state (reset: 0, the model's start)
            pitch_s = Signal(signed(ab))
            ok = inp.ok if self.held_input else Signal()
            if not self.spi_fed:
                gy_bits = Signal(10, reset_less=True)  # gy bits 6..15 until PRED_P
            in_pred = (phase == _Phase.PRED_R) | (phase == _Phase.PRED_P)
            m.d.comb += in_filter.eq((phase == _Phase.ROLL_F) | (phase == _Phase.PITCH_F))
            on_pitch = (phase == _Phase.PITCH_F) | (phase == _Phase.PRED_P)
            st0 = Mux(on_pitch, pitch_s[0], roll_s[0])
            with m.If(in_pred):  # pred = angle + (rate >>> 6)      -> the state
                m.d.comb += [za.eq(st0), zb.eq(z[0]), zs.eq(0)]
            with m.If(in_filter):
                with m.If(p == 0):  # innov = meas - pred              -> z
                    m.d.comb += [za.eq(z[0]), zb.eq(st0), zs.eq(1)]
                with m.Else():  # angle = pred + (innov >>> 6)         -> the state
                    m.d.comb += [za.eq(st0), zb.eq(z[6]), zs.eq(0)]
        cin_z = Mux(first, zs, cz)
        sum_z, co_z = _serial_add(za, zb, zs, cin_z)

        if not filt:
            roll = Signal(signed(ab))  # roll waits beside z for the pitch pass
            m.d.comb += [self.o.payload.roll.eq(roll), self.o.payload.pitch.eq(z)]
        # the pitch vector's y: 0 - (ax >>> 1) - (ax >>> 2) - (ax >>> 4) (= the model's
        # -((ax>>>1) + (ax>>>2) + (ax>>>4)): floor shifts, exact sums) in three passes of y's
        # adder; (ax >>> s) bit k is ax bit min(k + s, 15), i.e. ax_bits[min(k + s - 1, 14)]
        in_axn = phase == _Phase.AXN
        ax_ext = Cat(ax_bits, *([ax_bits[-1]] * (W + 4 - (WIDTH - 1))))
        with m.If(in_axn):
            m.d.comb += [ya.eq(y[0]), yb.eq(ax_ext.bit_select(
                k + Mux(p == 0, 0, Mux(p == 1, 1, 3)), 1)), ys.eq(1)]
            m.d.sync += [y.eq(Cat(y[1:], sum_y)), cy.eq(co_y), k.eq(k + 1)]
            with m.If(k == W - 1):
                m.d.sync += [k.eq(0), p.eq(p + 1), sy.eq(sum_y)]
                with m.If(p == 2):
                    m.d.sync += [p.eq(0), phase.eq(_Phase.ROLL_F if filt else _Phase.PITCH)]
        busy = (phase == _Phase.ROLL) | (phase == _Phase.PITCH)
        m.d.comb += [
            self.i.ready.eq(phase == _Phase.IDLE),
            self.o.valid.eq(phase == _Phase.OUT),
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
            with m.If(k == W - 1):
                m.d.sync += [k.eq(0), p.eq(p + 1), sx.eq(sum_x), sy.eq(sum_y)]
                with m.If(last_pass):
                    with m.If(phase == _Phase.ROLL):
                        # x (>= 0) is the magnitude K |(x, y)|: saturate it to 16 bits
                        mag = Cat(x[1:], sum_x)
                        over = mag > 32767
                        m.d.sync += [sat.eq(over & ok) if filt else sat.eq(over),
                                     phase.eq(_Phase.AXN)]
                        if not filt:
                            m.d.sync += roll.eq(z)
                        m.d.sync += load(Mux(over, Const(32767, signed(16)), mag[:16]),
                                         Const(0, signed(16)))
                    with m.Else():
                        m.d.sync += phase.eq(_Phase.PITCH_F if filt else _Phase.OUT)
                        if filt:
                            m.d.sync += p.eq(0)
        if filt:
            # 16-clock passes on the z adder; x, y (the pitch vector) wait. ok = 0 (failed
            # sensor check): the state rotates unchanged (the schedule stays the same)
            with m.If(in_filter | in_pred):
                m.d.sync += [cz.eq(co_z), k.eq(k + 1)]
                new_st = Mux((in_pred | (p == 1)) & ok, sum_z, st0)
                with m.If(on_pitch):
                    m.d.sync += pitch_s.eq(Cat(pitch_s[1:], new_st))
                with m.Else():
                    m.d.sync += roll_s.eq(Cat(roll_s[1:], new_st))
            with m.If(in_pred):
                # z[:10] holds rate bits 6..15: an arithmetic shift puts bit min(k + 6, 15)
                # at z[0] in clock k
                m.d.sync += z[:10].eq(Cat(z[1:10], z[9]))
                with m.If(k == ab - 1):
                    m.d.sync += k.eq(0)
                    if self.spi_fed:
                        m.d.sync += phase.eq(_Phase.IDLE)  # back to the burst
                    else:
                        with m.If(phase == _Phase.PRED_R):
                            m.d.sync += [z[:10].eq(gy_bits), phase.eq(_Phase.PRED_P)]
                        with m.Else():
                            m.d.sync += phase.eq(_Phase.ROLL)
            with m.If(in_filter):
                with m.If(p == 0):
                    m.d.sync += z.eq(Cat(z[1:], sum_z))
                with m.Else():  # arithmetic shift: z[6] is innov bit min(k + 6, 15)
                    m.d.sync += z.eq(Cat(z[1:], z[-1]))
                with m.If(k == ab - 1):
                    m.d.sync += [k.eq(0), p.eq(p + 1)]
                    with m.If(p == 1):
                        m.d.sync += p.eq(0)
                        with m.If(on_pitch):
                            m.d.sync += phase.eq(_Phase.OUT)
                        with m.Else():
                            m.d.sync += phase.eq(_Phase.PITCH)
            m.d.comb += [self.o.payload.roll.eq(roll_s), self.o.payload.pitch.eq(pitch_s),
                         self.o.payload.ok.eq(ok)]
        with m.Switch(phase):
            with m.Case(_Phase.IDLE):
                if self.spi_fed:
                    # bits 15..1 of az into x, of ay into y, MSB first (bits 17..15 are set
                    # by the sign extension at the load below)
                    with m.If(self.shift_az):
                        m.d.sync += x.eq(Cat(self.spi_bit, x[:-1]))
                    with m.If(self.shift_ay):
                        m.d.sync += y.eq(Cat(self.spi_bit, y[:-1]))
                    if filt:
                        # gx (then gy) bits 15..6 into z[:10]; after the last one the state
                        # takes the rate (the prediction needs no measurement): 16 clocks,
                        # inside the bits the chip drops before the next word
                        with m.If(self.shift_gx | self.shift_gy):
                            m.d.sync += z[:10].eq(Cat(self.spi_bit, z[:9]))
                        with m.If(self.last_gx):
                            m.d.sync += [phase.eq(_Phase.PRED_R), k.eq(0)]
                        with m.If(self.last_gy):
                            m.d.sync += [phase.eq(_Phase.PRED_P), k.eq(0)]
                with m.If(self.i.valid):
                    if not self.held_input:
                        ax = inp.ax
                        m.d.sync += ax_bits.eq(ax[1:])
                        if filt:
                            m.d.sync += [z[:10].eq(inp.gx[6:]), gy_bits.eq(inp.gy[6:]),
                                         ok.eq(inp.ok)]
                    if self.spi_fed:
                        m.d.sync += load(x[:WIDTH - 1].as_signed(), y[:WIDTH - 1].as_signed())
                    else:
                        m.d.sync += load(inp.az >> 1, inp.ay >> 1)
                    if filt and not self.spi_fed:
                        m.d.sync += [phase.eq(_Phase.PRED_R), k.eq(0)]
                    else:
                        m.d.sync += phase.eq(_Phase.ROLL)
            with m.Case(_Phase.OUT):
                with m.If(self.o.ready):
                    m.d.sync += phase.eq(_Phase.IDLE)
        return m


class TinyKalmanSerialDatapath(TinyKalmanSerialCordic):
    """The serial chip's whole arithmetic: the bit-serial CORDIC (roll, then pitch) and the
    steady-state filter run bit-serially on the CORDIC's z adder (16-clock passes:
    ``pred = angle + (rate >>> 6)`` into the state, first; after each angle ``innov = meas -
    pred`` into z, then ``angle = pred + (innov >>> 6)`` into the state, ``innov >>> 6`` read
    at bit 6 of z while z shifts arithmetically). The measured angle is never stored beside z.

    Input :data:`~navgate.systems.tinykalman.datapath.DATAPATH_IN` (``ok = 0``: the sample
    failed the sensor check; the state is held, the schedule is the same); output
    ``{roll, pitch, sat, ok}``: the filter state (also the packet's bytes), ``sat`` = mag_yz
    saturated in a used sample. ``LATENCY``: as a stream block ``667 + 2 * 16 + 2 * 2 * 16 =
    763`` clocks (the two predictions run after the input is taken); in the chip
    (``spi_fed``) ``667 + 2 * 2 * 16 = 731`` (the predictions ran during the burst).
    """

    LATENCY = SERIAL_DATAPATH_LATENCY
    THROUGHPUT = Fraction(1, SERIAL_DATAPATH_LATENCY + 1)
    _FILTER = True

    def _signature(self):
        return {"i": In(stream.Signature(DATAPATH_IN)),
                "o": Out(stream.Signature(SERIAL_DATAPATH_OUT))}
