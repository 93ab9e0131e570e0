"""Seed 000 ``uart_rx_lidar``: TF-Luna UART receiver (115200 8N1) and 9-byte frame parser.

* Receiver: RX passes a two-flip-flop synchroniser (the line is asynchronous to ``sync``);
  16x oversampling from a tick every ``cfg_div + 1`` cycles (the seed's LIDAR_CFG[7:0] "baud
  div": 100 MHz / (16 * 54) = 115,741 baud, +0.47 %, for ``cfg_div = 53``). A start bit is
  confirmed at its middle (8 ticks), data bits are sampled at their middles, a 0 stop bit is a
  framing error (the character is dropped, counted, and the parser needs nine fresh bytes).
* Frame parser (:mod:`navgate.devices.tfluna`): a sliding nine-byte window; a frame is
  accepted when the window starts 0x59 0x59, its checksum (low byte of the sum of the first
  eight bytes) matches and nine bytes have arrived since the last accepted frame. The window
  resynchronises after noise bytes, truncated or dropped frames within one frame. A header
  with a wrong checksum is counted. The strength rule of the data sheet (100 <= strength <
  65535) sets ``reliable``; unreliable frames are delivered with ``reliable = 0`` (the ranger
  reports "no return" that way), never as a valid range.
* Counters: bytes received, frames accepted, checksum errors, framing errors, unreliable
  frames, timeouts (no accepted frame for ``timeout_bits`` bit times: the missing-device and
  dropped-frame detector; ``timed_out`` stays high until the next frame).
* Output: one registered frame; a frame that arrives while the previous one is still waiting
  (``o.ready`` low) is dropped and counted in ``overrun_count``.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth.hdl import Cat, Module, Signal, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.wiring import In, Out

from navgate.devices import tfluna

FRAME_LAYOUT = data.StructLayout({"dist": unsigned(16), "strength": unsigned(16),
                                  "temp": unsigned(16), "reliable": unsigned(1)})
DEFAULT_DIV = 53  # 100 MHz clock


class UartRxLidar(wiring.Component):
    """TF-Luna 115200 8N1 receiver and 9-byte frame parser (seed 000 uart_rx_lidar)."""

    LATENCY = 3  #: cycles from the last stop bit's sample to ``o.valid``
    #: at most one frame per 9 characters of 10 bits of 16 ticks of (DEFAULT_DIV + 1) cycles
    THROUGHPUT = Fraction(1, 9 * 10 * 16 * (DEFAULT_DIV + 1))

    def __init__(self, timeout_bits: int = 2304, counter_bits: int = 16):
        self.timeout_bits = timeout_bits
        super().__init__({
            "rx": In(1, init=1),
            "cfg_div": In(8, init=DEFAULT_DIV), "cfg_enable": In(1, init=1),
            "o": Out(stream.Signature(FRAME_LAYOUT)),
            "byte_count": Out(counter_bits), "frame_count": Out(counter_bits),
            "checksum_errors": Out(counter_bits), "framing_errors": Out(counter_bits),
            "unreliable_count": Out(counter_bits), "timeout_count": Out(counter_bits),
            "overrun_count": Out(counter_bits),
            "timed_out": Out(1), "sensor_error": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        rx = Signal(init=1)
        m.submodules.rx_sync = FFSynchronizer(self.rx, rx, init=1, stages=2)

        # ---- 16x oversampling receiver ----
        div = Signal(8)
        tick = Signal()
        with m.If(div >= self.cfg_div):
            m.d.sync += div.eq(0)
            m.d.comb += tick.eq(1)
        with m.Else():
            m.d.sync += div.eq(div + 1)
        sub = Signal(4)
        nbit = Signal(range(9))
        shift = Signal(8)
        byte = Signal(8)
        got = Signal()
        ferr = Signal()
        bit_tick = Signal()  # one per bit time, for the timeout
        btc = Signal(4)
        with m.If(tick):
            m.d.sync += btc.eq(btc + 1)
            m.d.comb += bit_tick.eq(btc == 15)
        with m.FSM(name="rx_fsm"):
            with m.State("IDLE"):
                with m.If(tick & ~rx & self.cfg_enable):
                    m.d.sync += sub.eq(0)
                    m.next = "START"
            with m.State("START"):
                with m.If(tick):
                    m.d.sync += sub.eq(sub + 1)
                    with m.If(sub == 6):  # 8th tick after the falling edge: mid start bit
                        with m.If(rx):
                            m.next = "IDLE"  # glitch
                        with m.Else():
                            m.d.sync += [sub.eq(0), nbit.eq(0)]
                            m.next = "DATA"
            with m.State("DATA"):
                with m.If(tick):
                    m.d.sync += sub.eq(sub + 1)
                    with m.If(sub == 15):
                        m.d.sync += [shift.eq(Cat(shift[1:], rx)), nbit.eq(nbit + 1)]
                        with m.If(nbit == 7):
                            m.next = "STOP"
            with m.State("STOP"):
                with m.If(tick):
                    m.d.sync += sub.eq(sub + 1)
                    with m.If(sub == 15):
                        m.d.sync += byte.eq(shift)
                        with m.If(rx):
                            m.d.comb += got.eq(1)
                            m.next = "IDLE"
                        with m.Else():
                            m.d.comb += ferr.eq(1)
                            m.next = "BREAK"
            with m.State("BREAK"):  # wait for the line to return high
                with m.If(tick & rx):
                    m.next = "IDLE"

        # ---- sliding-window frame parser ----
        win = [Signal(8, name=f"w{k}") for k in range(tfluna.FRAME_BYTES)]
        fill = Signal(range(tfluna.FRAME_BYTES + 1))
        check = Signal()
        m.d.sync += check.eq(0)
        got_d = Signal()
        m.d.sync += got_d.eq(got)
        with m.If(got_d):  # ``byte`` is registered one cycle after ``got``
            m.d.sync += [win[k].eq(win[k + 1]) for k in range(tfluna.FRAME_BYTES - 1)]
            m.d.sync += [win[-1].eq(byte), check.eq(1), self.byte_count.eq(self.byte_count + 1)]
            with m.If(fill != tfluna.FRAME_BYTES):
                m.d.sync += fill.eq(fill + 1)
        csum = Signal(8)
        acc = win[0]
        for k in range(1, 8):
            acc = (acc + win[k])[:8]
        m.d.comb += csum.eq(acc)
        header = (win[0] == tfluna.HEADER) & (win[1] == tfluna.HEADER)
        full = fill == tfluna.FRAME_BYTES
        strength = Cat(win[4], win[5])
        accept = Signal()
        m.d.comb += accept.eq(check & full & header & (csum == win[8]))
        m.d.comb += self.sensor_error.eq((check & full & header & (csum != win[8])) | ferr)
        with m.If(ferr):
            m.d.sync += [fill.eq(0), self.framing_errors.eq(self.framing_errors + 1)]
        with m.If(check & full & header & (csum != win[8])):
            m.d.sync += self.checksum_errors.eq(self.checksum_errors + 1)

        # ---- output register, counters, timeout ----
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += self.o.valid.eq(0)
        tcount = Signal(range(self.timeout_bits + 1))
        with m.If(bit_tick):
            with m.If(tcount == self.timeout_bits - 1):
                m.d.sync += [tcount.eq(0), self.timed_out.eq(1),
                             self.timeout_count.eq(self.timeout_count + 1)]
            with m.Else():
                m.d.sync += tcount.eq(tcount + 1)
        with m.If(accept):
            m.d.sync += [fill.eq(0), tcount.eq(0), self.timed_out.eq(0),
                         self.frame_count.eq(self.frame_count + 1)]
            reliable = (strength >= tfluna.STRENGTH_MIN) & (strength != 0xFFFF)
            with m.If(~reliable):
                m.d.sync += self.unreliable_count.eq(self.unreliable_count + 1)
            with m.If(self.o.valid & ~self.o.ready):
                m.d.sync += self.overrun_count.eq(self.overrun_count + 1)
            with m.Else():
                m.d.sync += [self.o.valid.eq(1), self.o.payload.dist.eq(Cat(win[2], win[3])),
                             self.o.payload.strength.eq(strength),
                             self.o.payload.temp.eq(Cat(win[6], win[7])),
                             self.o.payload.reliable.eq(reliable)]
        return m
