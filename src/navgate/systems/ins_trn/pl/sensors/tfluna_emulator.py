"""TF-Luna UART transmitter emulator in gateware: 9-byte Benewake data frames from a stream of
(distance, strength, temperature) words, for FPGA co-simulation and hardware-in-the-loop tests.

Reference: the Benewake TF-Luna frame as navgate.devices.tfluna encodes it
(:func:`~navgate.devices.tfluna.encode_frames`): ``0x59 0x59 Dist_L Dist_H Amp_L Amp_H Temp_L
Temp_H Checksum``, the checksum the low byte of the sum of the first eight bytes; UART 8N1,
LSB first, idle high (115200 baud on the part).

Each accepted sample is sent as one frame of nine characters back to back (start bit, eight
data bits LSB first, one stop bit; no idle time between the characters of a frame). A bit
lasts ``cfg_bit_cycles`` clock cycles (a run-time input, >= 1: 868 gives 115,207 baud at
100 MHz, +0.006 %). Frames are paced by the producer: ``samples.ready`` is high only while
no frame is being sent (one frame buffered, in flight), so a producer at the part's 100 Hz
gets one frame per sample, and one faster than a frame time (90 bit times) is stalled, never
dropped. The fields are the raw frame words: ``dist`` in the ranger's unit (cm on the
TF-Luna), ``strength``, and ``temp`` = (degC + 256) * 8, all unsigned 16. ``tx`` is a
registered output (1 at idle); ``frames`` counts the frames completed (stop bit of the ninth
character sent).
"""

from __future__ import annotations

from fractions import Fraction

from amaranth.hdl import Cat, Const, Module, Signal, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.devices import tfluna

SAMPLE_LAYOUT = data.StructLayout({"dist": unsigned(16), "strength": unsigned(16),
                                   "temp": unsigned(16)})
#: 100 MHz / 115200 baud, rounded
DEFAULT_BIT_CYCLES = 868
CHAR_BITS = 1 + tfluna.DATA_BITS + tfluna.STOP_BITS  # 10


def frame_cycles(bit_cycles: int) -> int:
    """Cycles one frame occupies the line (9 characters of 10 bits)."""
    return tfluna.FRAME_BYTES * CHAR_BITS * bit_cycles


class TfLunaEmulator(wiring.Component):
    """Benewake 9-byte frame UART transmitter (8N1) fed by a (dist, strength, temp) stream."""

    #: cycles from the sample accepted to the start bit on ``tx``
    LATENCY = 1
    #: one frame per 90 bit times of DEFAULT_BIT_CYCLES cycles (plus the accept cycle)
    THROUGHPUT = Fraction(1, frame_cycles(DEFAULT_BIT_CYCLES) + 1)

    def __init__(self, counter_bits: int = 32):
        super().__init__({
            "tx": Out(1, init=1), "cfg_bit_cycles": In(16, init=DEFAULT_BIT_CYCLES),
            "samples": In(stream.Signature(SAMPLE_LAYOUT)), "frames": Out(counter_bits),
        })

    def elaborate(self, platform):
        m = Module()
        cur = Signal(SAMPLE_LAYOUT)
        nbyte = Signal(range(tfluna.FRAME_BYTES + 1))  # characters started
        nbit = Signal(range(CHAR_BITS))
        cnt = Signal(16)
        sr = Signal(CHAR_BITS)  # the character being sent, LSB (start bit) first on tx
        csum = Signal(8)

        header = Const(tfluna.HEADER, 8)
        char = Signal(8)  # character ``nbyte`` of the frame
        with m.Switch(nbyte):
            for k, v in enumerate([header, header, cur.dist[:8], cur.dist[8:],
                                   cur.strength[:8], cur.strength[8:], cur.temp[:8],
                                   cur.temp[8:], csum]):
                with m.Case(k):
                    m.d.comb += char.eq(v)

        def start_char():
            # start bit 0, data LSB first, stop bit 1; the checksum accumulates bytes 0..7
            m.d.sync += [sr.eq(Cat(Const(0, 1), char, Const(1, 1))), self.tx.eq(0),
                         nbit.eq(0), cnt.eq(1), nbyte.eq(nbyte + 1), csum.eq(csum + char)]

        with m.FSM(name="tx"):
            with m.State("IDLE"):
                m.d.comb += self.samples.ready.eq(1)
                with m.If(self.samples.valid):
                    m.d.sync += [cur.eq(self.samples.payload), nbyte.eq(0), csum.eq(0)]
                    m.next = "LOAD"
            with m.State("LOAD"):
                start_char()
                m.next = "SEND"
            with m.State("SEND"):
                m.d.sync += cnt.eq(cnt + 1)
                with m.If(cnt >= self.cfg_bit_cycles):
                    with m.If(nbit == CHAR_BITS - 1):
                        with m.If(nbyte == tfluna.FRAME_BYTES):
                            m.d.sync += [self.frames.eq(self.frames + 1), self.tx.eq(1)]
                            m.next = "IDLE"
                        with m.Else():
                            start_char()
                    with m.Else():
                        m.d.sync += [cnt.eq(1), nbit.eq(nbit + 1), sr.eq(sr >> 1),
                                     self.tx.eq(sr[1])]
        return m
