"""Seed 001 TinyKalman gateware: accelerometer angles (:class:`TinyKalmanCordic`) and the
steady-state Kalman filter (block ``kalman_steady``), bit-exact to
:mod:`navgate.systems.tinykalman.model`.

Reference: seed 001 ("Angle Estimation (CORDIC)", "Sensor Fusion"); the model's docstring
gives the arithmetic step for step.

:class:`TinyKalmanCordic` (not a registered block: YoWASP Yosys's ``synth_xilinx`` aborts on
it alone, see ``navgate.systems.BLOCKS``; the shared ``cordic_atan2`` name belongs to the shared
unrolled core). One shared iterative CORDIC
(:class:`navgate.gateware.cordic.CordicAtan2Iterative`, 16-bit words, 16 iterations, 16-bit
binary angles, no guard bits: exactly ``cordic_vectoring(..., 16, 16, angle_bits=16)`` of the
model) is used twice per sample:

1. roll: ``(mag, roll) = CORDIC(x = az >>> 1, y = ay >>> 1)``;
2. pitch: ``(_, pitch) = CORDIC(x = min(mag, 32767), y = -((ax>>>1) + (ax>>>2) + (ax>>>4)))``.

``sat`` flags ``mag > 32767`` (the saturation the model counts). Input stream
``{ax, ay, az}``, output ``{roll, pitch, mag, sat}``. ``LATENCY = 37`` cycles from the accepted
input to the valid output (1 + 17 for the roll pass, 1 + 17 for the pitch pass, 1 to hand
over), ``THROUGHPUT = 1/38`` (the output cycle); both measured in the tests.

:class:`KalmanSteady` (block ``kalman_steady``): both axes in parallel, 16-bit wrap-around
words, ``pred = angle + (rate >>> 6)``, ``angle = pred + ((meas - pred) >>> 6)``; roll uses
gx, pitch gy. Input ``{roll_m, pitch_m, gx, gy, use}``: ``use = 0`` (the sample failed the
sensor check) keeps the state. Output ``{roll, pitch}``: the state after the update.
``LATENCY = 1``, ``THROUGHPUT = 1``. Reset clears the state to 0.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth import Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, enum, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.cordic import CordicAtan2Iterative
from navgate.gateware.parameters import CheckedParameters
from navgate.nav import validate
from navgate.systems.tinykalman.model import ANGLE_BITS, ITERATIONS, WIDTH

__all__ = ["TinyKalmanCordic", "KalmanSteady", "TinyKalmanDatapath", "CORDIC_LATENCY"]

CORDIC_LATENCY = 37
CORDIC_INTERVAL = 38  #: cycles between accepted inputs at full rate

ANGLES_IN = data.StructLayout({"ax": signed(16), "ay": signed(16), "az": signed(16)})
ANGLES_OUT = data.StructLayout({"roll": signed(16), "pitch": signed(16), "mag": unsigned(17),
                                "sat": unsigned(1)})


class _Phase(enum.Enum, shape=3):
    IDLE = 0
    ISSUE_ROLL = 1
    WAIT_ROLL = 2
    ISSUE_PITCH = 3
    WAIT_PITCH = 4
    OUT = 5


class TinyKalmanCordic(wiring.Component):
    """Roll and pitch from accelerometer words through one iterative CORDIC used twice."""

    LATENCY = CORDIC_LATENCY
    THROUGHPUT = Fraction(1, CORDIC_INTERVAL)

    def __init__(self):
        super().__init__({
            "i": In(stream.Signature(ANGLES_IN)),
            "o": Out(stream.Signature(ANGLES_OUT)),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.cordic = cordic = CordicAtan2Iterative(
            width=WIDTH, iterations=ITERATIONS, angle_bits=ANGLE_BITS, guard_bits=0)
        phase = Signal(_Phase)
        ax_neg = Signal(signed(16))  # -((ax>>>1) + (ax>>>2) + (ax>>>4)), |.| <= 26624
        x_in = Signal(signed(16))
        y_in = Signal(signed(16))
        res = Signal(ANGLES_OUT)

        ax = self.i.payload.ax
        ax_scaled = (ax >> 1) + (ax >> 2) + (ax >> 4)
        mag = cordic.o.payload.magnitude
        m.d.comb += [
            cordic.o.ready.eq(1),
            cordic.i.payload.x.eq(x_in),
            cordic.i.payload.y.eq(y_in),
            cordic.i.valid.eq((phase == _Phase.ISSUE_ROLL) | (phase == _Phase.ISSUE_PITCH)),
            self.i.ready.eq(phase == _Phase.IDLE),
            self.o.valid.eq(phase == _Phase.OUT),
            self.o.payload.eq(res),
        ]
        with m.Switch(phase):
            with m.Case(_Phase.IDLE):
                with m.If(self.i.valid):
                    m.d.sync += [
                        ax_neg.eq(-ax_scaled),
                        x_in.eq(self.i.payload.az >> 1),
                        y_in.eq(self.i.payload.ay >> 1),
                        phase.eq(_Phase.ISSUE_ROLL),
                    ]
            with m.Case(_Phase.ISSUE_ROLL):
                with m.If(cordic.i.ready):
                    m.d.sync += phase.eq(_Phase.WAIT_ROLL)
            with m.Case(_Phase.WAIT_ROLL):
                with m.If(cordic.o.valid):
                    sat = mag > 32767
                    m.d.sync += [
                        res.roll.eq(cordic.o.payload.angle),
                        res.mag.eq(mag),
                        res.sat.eq(sat),
                        x_in.eq(Mux(sat, 32767, mag)),
                        y_in.eq(ax_neg),
                        phase.eq(_Phase.ISSUE_PITCH),
                    ]
            with m.Case(_Phase.ISSUE_PITCH):
                with m.If(cordic.i.ready):
                    m.d.sync += phase.eq(_Phase.WAIT_PITCH)
            with m.Case(_Phase.WAIT_PITCH):
                with m.If(cordic.o.valid):
                    m.d.sync += [res.pitch.eq(cordic.o.payload.angle), phase.eq(_Phase.OUT)]
            with m.Case(_Phase.OUT):
                with m.If(self.o.ready):
                    m.d.sync += phase.eq(_Phase.IDLE)
        return m


KALMAN_IN = data.StructLayout({"roll_m": signed(16), "pitch_m": signed(16), "gx": signed(16),
                               "gy": signed(16), "use": unsigned(1)})
KALMAN_OUT = data.StructLayout({"roll": signed(16), "pitch": signed(16)})


class KalmanSteady(CheckedParameters, wiring.Component):
    """Steady-state Kalman filter with ``>>> rate_shift`` and ``>>> k_shift`` gains, two axes."""

    LATENCY = 1
    THROUGHPUT = 1

    @classmethod
    def check_parameters(cls, rate_shift: int, k_shift: int) -> None:
        for name, v in (("rate_shift", rate_shift), ("k_shift", k_shift)):
            if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 15:
                raise ValueError(f"KalmanSteady: {name} must be an integer in [0, 15], got {v!r}")

    def __init__(self, rate_shift: int = 6, k_shift: int = 6):
        self.rate_shift = rate_shift
        self.k_shift = k_shift
        super().__init__({
            "i": In(stream.Signature(KALMAN_IN)),
            "o": Out(stream.Signature(KALMAN_OUT)),
        })

    def _update(self, m, angle, rate, meas, name):
        pred = Signal(signed(16), name=f"{name}_pred")
        innov = Signal(signed(16), name=f"{name}_innov")
        new = Signal(signed(16), name=f"{name}_new")
        m.d.comb += [
            pred.eq(angle + (rate >> self.rate_shift)),  # truncation = 16-bit wrap
            innov.eq(meas - pred),
            new.eq(pred + (innov >> self.k_shift)),
        ]
        return new

    def elaborate(self, platform):
        m = Module()
        roll = Signal(signed(16))
        pitch = Signal(signed(16))
        out_valid = Signal()
        p = self.i.payload
        roll_new = self._update(m, roll, p.gx, p.roll_m, "roll")
        pitch_new = self._update(m, pitch, p.gy, p.pitch_m, "pitch")
        accept = self.i.valid & self.i.ready
        m.d.comb += [
            self.i.ready.eq(~out_valid | self.o.ready),
            self.o.valid.eq(out_valid),
            self.o.payload.roll.eq(roll),
            self.o.payload.pitch.eq(pitch),
        ]
        with m.If(self.o.ready):
            m.d.sync += out_valid.eq(0)
        with m.If(accept):
            m.d.sync += out_valid.eq(1)
            with m.If(p.use):
                m.d.sync += [roll.eq(roll_new), pitch.eq(pitch_new)]
        return m


DATAPATH_IN = data.StructLayout({"ax": signed(16), "ay": signed(16), "az": signed(16),
                                 "gx": signed(16), "gy": signed(16), "ok": unsigned(1)})
DATAPATH_OUT = data.StructLayout({"roll": signed(16), "pitch": signed(16),
                                  "roll_m": signed(16), "pitch_m": signed(16),
                                  "sat": unsigned(1), "ok": unsigned(1)})


class TinyKalmanDatapath(CheckedParameters, wiring.Component):
    """One sample in, the filtered angles out: :class:`TinyKalmanCordic` then
    :class:`KalmanSteady` (``ok = 0``: the sample failed the sensor check, state held).

    This is the chip's whole arithmetic between the SPI master and the packet sequencer, as a
    stream component for the verification harness. ``LATENCY = 38``, ``THROUGHPUT = 1/38``.
    """

    LATENCY = CORDIC_LATENCY + 1
    THROUGHPUT = Fraction(1, CORDIC_INTERVAL)

    @classmethod
    def check_parameters(cls, angles_cls=None, held_input: bool = False) -> None:
        held_input = validate.flag("TinyKalmanDatapath: held_input", held_input)
        if angles_cls is not None and not (isinstance(angles_cls, type) and issubclass(
                angles_cls, wiring.Component) and hasattr(angles_cls, "LATENCY")):
            raise ValueError("TinyKalmanDatapath: angles_cls must be an angle block class "
                             f"(TinyKalmanSerialCordic), got {angles_cls!r}")
        if held_input and angles_cls is None:
            raise ValueError("TinyKalmanDatapath: held_input needs the serial angle block")

    def __init__(self, angles_cls=None, held_input: bool = False):
        #: the angle block: :class:`TinyKalmanCordic` (default) or the bit-serial
        #: :class:`~navgate.systems.tinykalman.serial.TinyKalmanSerialCordic`
        self.angles_cls = TinyKalmanCordic if angles_cls is None else angles_cls
        #: ``held_input`` (serial chip only): the producer (the SPI master's word register)
        #: holds ``i.payload`` until the output is taken, so gx, gy, ok and ax are read from it
        #: and not copied into registers here
        self.held_input = validate.flag("TinyKalmanDatapath: held_input", held_input)
        if angles_cls is not None:
            self.LATENCY = angles_cls.LATENCY + 1
            self.THROUGHPUT = angles_cls.THROUGHPUT
        super().__init__({
            "i": In(stream.Signature(DATAPATH_IN)),
            "o": Out(stream.Signature(DATAPATH_OUT)),
        })

    def elaborate(self, platform):
        m = Module()
        if self.held_input:
            m.submodules.angles = angles = self.angles_cls(held_input=True)
        else:
            m.submodules.angles = angles = self.angles_cls()
        m.submodules.kalman = kalman = KalmanSteady()
        gx, gy, ok = Signal(16), Signal(16), Signal()
        roll_m, pitch_m, sat, ok_out = Signal(16), Signal(16), Signal(), Signal()
        p = self.i.payload
        m.d.comb += [
            angles.i.payload.ax.eq(p.ax),
            angles.i.payload.ay.eq(p.ay),
            angles.i.payload.az.eq(p.az),
            angles.i.valid.eq(self.i.valid),
            self.i.ready.eq(angles.i.ready),
        ]
        if self.held_input:
            m.d.comb += [gx.eq(p.gx), gy.eq(p.gy), ok.eq(p.ok)]
        else:
            with m.If(self.i.valid & angles.i.ready):
                m.d.sync += [gx.eq(p.gx), gy.eq(p.gy), ok.eq(p.ok)]
        ap = angles.o.payload
        m.d.comb += [
            kalman.i.payload.roll_m.eq(ap.roll),
            kalman.i.payload.pitch_m.eq(ap.pitch),
            kalman.i.payload.gx.eq(gx),
            kalman.i.payload.gy.eq(gy),
            kalman.i.payload.use.eq(ok),
            kalman.i.valid.eq(angles.o.valid),
            angles.o.ready.eq(kalman.i.ready),
        ]
        with m.If(angles.o.valid & kalman.i.ready):
            m.d.sync += [roll_m.eq(ap.roll), pitch_m.eq(ap.pitch), sat.eq(ap.sat & ok),
                         ok_out.eq(ok)]
        m.d.comb += [
            self.o.payload.roll.eq(kalman.o.payload.roll),
            self.o.payload.pitch.eq(kalman.o.payload.pitch),
            self.o.payload.roll_m.eq(roll_m),
            self.o.payload.pitch_m.eq(pitch_m),
            self.o.payload.sat.eq(sat),
            self.o.payload.ok.eq(ok_out),
            self.o.valid.eq(kalman.o.valid),
            kalman.o.ready.eq(self.o.ready),
        ]
        return m
