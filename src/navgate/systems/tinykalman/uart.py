"""Seed 001 TinyKalman gateware: 8N1 UART transmitter (``uart_tx`` block).

Reference: seed 001 ("Output: UART Serial output (9600 baud)"; pin ``uo_out[3]``). Frames as
:func:`navgate.systems.tinykalman.model.uart_frame_bits`: start bit 0, eight data bits LSB
first, stop bit 1, each ``baud_div`` system clocks. The default ``baud_div = 1042`` gives
10 MHz / 1042 = 9596.9 baud, -0.032 % from 9600 (a receiver tolerates a few percent).

Input: a stream of bytes. A byte accepted in cycle c drives the start bit from cycle c + 1
(``LATENCY = 1``); the next byte is accepted in the last cycle of the stop bit, so bytes go out
back to back (``THROUGHPUT`` = 1 / (10 ``baud_div``) bytes per cycle). ``tx`` idles high.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth import Array, Cat, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.parameters import CheckedParameters

__all__ = ["UartTx", "UartPacketTx", "BAUD_DIV_9600_AT_10MHZ"]

BAUD_DIV_9600_AT_10MHZ = 1042  #: round(10e6 / 9600)


class UartTx(CheckedParameters, wiring.Component):
    """8N1 UART transmitter, ``baud_div`` clocks per bit."""

    LATENCY = 1

    @classmethod
    def check_parameters(cls, baud_div):
        if not isinstance(baud_div, int) or not 1 <= baud_div <= 1 << 20:
            raise ValueError(f"UartTx: baud_div must be a positive integer, got {baud_div!r}")

    def __init__(self, baud_div: int = BAUD_DIV_9600_AT_10MHZ):
        self.baud_div = baud_div
        self.THROUGHPUT = Fraction(1, 10 * baud_div)
        super().__init__({
            "i": In(stream.Signature(8)),
            "tx": Out(1, init=1),
            "busy": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        cnt = Signal(range(self.baud_div))
        nbit = Signal(range(10))
        shift = Signal(9)  # data bits, then the stop bit
        busy = Signal()
        tick = cnt == self.baud_div - 1
        last = busy & tick & (nbit == 9)
        m.d.comb += [self.i.ready.eq(~busy | last), self.busy.eq(busy)]
        with m.If(busy):
            m.d.sync += cnt.eq(0 if self.baud_div == 1 else (cnt + 1) * ~tick)
            with m.If(tick):
                with m.If(nbit == 9):
                    m.d.sync += busy.eq(0)
                with m.Else():
                    m.d.sync += [self.tx.eq(shift[0]), shift.eq(shift >> 1), nbit.eq(nbit + 1)]
        with m.If(self.i.valid & self.i.ready):
            m.d.sync += [busy.eq(1), self.tx.eq(0), shift.eq(Cat(self.i.payload, 1)),
                         nbit.eq(0), cnt.eq(0)]
        return m


class UartPacketTx(CheckedParameters, wiring.Component):
    """8N1 transmitter of a whole ``n_bytes`` packet read in place (the serial chip's UART).

    ``start`` (while not ``busy``) sends the bytes of ``packet`` (byte 0 in bits 7..0, first
    on the line) back to back, each bit read from ``packet`` when it goes out: the producer
    holds ``packet`` while ``busy`` (the serial chip's filter state does), so there is no shift
    register; the ``tx`` flip-flop keeps the line free of glitches. Same line timing as
    :class:`UartTx` fed byte after byte: the start bit from the cycle after ``start``,
    ``10 * baud_div`` clocks per byte, ``busy`` until the last stop bit ends.
    """

    LATENCY = 1

    @classmethod
    def check_parameters(cls, n_bytes, baud_div):
        if not isinstance(baud_div, int) or not 1 <= baud_div <= 1 << 20:
            raise ValueError(f"UartPacketTx: baud_div must be a positive integer, "
                             f"got {baud_div!r}")
        if not isinstance(n_bytes, int) or n_bytes < 1:
            raise ValueError(f"UartPacketTx: n_bytes must be a positive integer, got {n_bytes!r}")

    def __init__(self, n_bytes: int, baud_div: int = BAUD_DIV_9600_AT_10MHZ):
        self.baud_div, self.n_bytes = baud_div, n_bytes
        self.THROUGHPUT = Fraction(1, 10 * baud_div * n_bytes)
        super().__init__({
            "start": In(1),
            "packet": In(8 * n_bytes),
            "tx": Out(1, init=1),
            "busy": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        # set when a packet starts: no reset
        cnt = Signal(range(self.baud_div), reset_less=True)
        nbit = Signal(range(10), reset_less=True)  # 0 start bit, 1..8 data, 9 stop bit
        index = Signal(range(self.n_bytes), reset_less=True)
        busy = self.busy
        tick = cnt == self.baud_div - 1
        byte = Array(self.packet[8 * i:8 * i + 8] for i in range(self.n_bytes))[index]
        # the bit after slot nbit: data bit nbit (nbit 0..7), then the stop bit
        nxt = Mux(nbit == 8, 1, byte.bit_select(nbit[:3], 1))
        with m.If(busy):
            m.d.sync += cnt.eq(0 if self.baud_div == 1 else (cnt + 1) * ~tick)
            with m.If(tick):
                with m.If(nbit == 9):
                    with m.If(index == self.n_bytes - 1):
                        m.d.sync += busy.eq(0)
                    with m.Else():
                        m.d.sync += [index.eq(index + 1), nbit.eq(0), self.tx.eq(0)]
                with m.Else():
                    m.d.sync += [self.tx.eq(nxt), nbit.eq(nbit + 1)]
        with m.If(self.start & ~busy):
            m.d.sync += [busy.eq(1), self.tx.eq(0), nbit.eq(0), cnt.eq(0), index.eq(0)]
        return m
