"""Seed 001 TinyKalman gateware: the chip (``tinykalman_top``), a TinyTapeout user module.

Reference: seed 001 (features, pinout, data format); the blocks it connects:
:class:`~navgate.systems.tinykalman.spi.Mpu6500Spi` -> :class:`~.datapath.TinyKalmanCordic`
-> :class:`~.datapath.KalmanSteady` (the two together: :class:`~.datapath.TinyKalmanDatapath`)
-> packet sequencer -> :class:`~.uart.UartTx`.

Ports (TinyTapeout convention): ``ui_in[7:0]``, ``uo_out[7:0]``, ``uio_in[7:0]``,
``uio_out[7:0]``, ``uio_oe[7:0]``, ``ena``, ``clk``, ``rst_n`` (active low, synchronous).
Seed pinout: MISO = ``ui_in[0]``; MOSI, SCLK, CS_N, TX = ``uo_out[0..3]``. navgate additions
(the seed leaves them free): ``uio_out[0]`` = sensor fault (the last sample's WHO_AM_I was not
0x70: device absent, MISO stuck, wrong part), ``uio_out[1]`` = mag_yz saturated in the last
used sample, ``uio_oe = 0x03``; ``uo_out[7:4] = 0``; ``ena`` is ignored (the tile is clocked
only while selected).

Schedule: a timer of ``sample_period`` clocks (default 100,000 = 10 ms at 10 MHz, the 100 Hz
loop) starts the SPI master right after reset and then every period. WHO_AM_I and burst read
(``spi_cycles(spi_div)``), the two CORDIC passes, the filter update, then the 6-byte packet
``DE AD roll pitch`` (model :func:`~navgate.systems.tinykalman.model.encode_packet`). A sample
that fails the WHO_AM_I check leaves the filter state unchanged and the packet repeats it
(the model's :class:`~navgate.systems.tinykalman.model.TinyKalman` does the same). The chip
keeps streaming whatever the sensor does.

``variant``: ``"parallel"`` (default, the word-parallel iterative CORDIC) or ``"serial"``
(:mod:`navgate.systems.tinykalman.serial`: the bit-serial CORDIC and filter; the SPI master
shifts MISO bits straight into the registers that use them (ay, az into the CORDIC's x, y; the
rates into z; ax into its own 15-bit register) and checks WHO_AM_I bit by bit; the packet goes
out bit by bit from the filter state (:class:`~.uart.UartPacketTx`); the sample timer is an
LFSR (:func:`lfsr_timer`); registered as block ``tinykalman_serial_top``,
:func:`TinyKalmanSerialTop`). Same pins and bytes. In the serial chip the status pins change
while a sample is computed (fault when the data path takes it, sat after the roll pass), before
its packet; in the parallel chip when its packet starts.

Elaboration parameters: ``spi_div`` (clocks per SCLK half period, default 5: 1 MHz),
``baud_div`` (clocks per UART bit, default 1042: 9596.9 baud), ``sample_period`` (clocks);
``sample_period >= min_sample_period(spi_div, baud_div)`` so that each sample's packet is out
before the next sample starts (checked). Timing figures: :func:`timing`.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth import Array, Cat, ClockDomain, ClockSignal, Const, Module, Mux, ResetInserter, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.parameters import CheckedParameters
from navgate.nav import validate
from navgate.systems.tinykalman.datapath import CORDIC_LATENCY, TinyKalmanDatapath
from navgate.systems.tinykalman.model import HEADER, PACKET_LEN, WHO_AM_I_VALUE
from navgate.systems.tinykalman.serial import (
    SERIAL_CORDIC_LATENCY,
    SERIAL_DATAPATH_LATENCY,
    TinyKalmanSerialDatapath,
)
from navgate.systems.tinykalman.spi import Mpu6500Spi, spi_cycles
from navgate.systems.tinykalman.uart import BAUD_DIV_9600_AT_10MHZ, UartPacketTx, UartTx

__all__ = ["TinyKalmanCore", "TinyKalmanTop", "TinyKalmanSerialTop", "min_sample_period",
           "timing", "CLK_HZ", "TT_MODULE_NAME", "VARIANTS", "cordic_latency",
           "datapath_latency", "lfsr_timer", "LFSR_TAPS"]

CLK_HZ = 10_000_000
TT_MODULE_NAME = "tt_um_navgate_tinykalman"
DEFAULT_SPI_DIV = 5
DEFAULT_SAMPLE_PERIOD = CLK_HZ // 100
#: clocks from CS_N rising (end of the burst) to the first start bit: the CS_N-high gap
#: (spi_div), the SPI result register (1), CORDIC (37), filter (1), packet register and UART
#: start bit (1); measured in the tests
#: ``variant``: "parallel" (the iterative CORDIC, word-parallel) or "serial" (the bit-serial
#: CORDIC of :mod:`navgate.systems.tinykalman.serial`, the chip that fits one SG13G2 tile)
VARIANTS = ("parallel", "serial")


def cordic_latency(variant: str = "parallel") -> int:
    """Clocks from the angle block's accepted input to its valid output."""
    if variant == "parallel":
        return CORDIC_LATENCY
    if variant == "serial":
        return SERIAL_CORDIC_LATENCY
    raise ValueError(f"TinyKalman: variant must be one of {', '.join(VARIANTS)}; "
                     f"got {variant!r}")


def datapath_latency(variant: str = "parallel") -> int:
    """Clocks from the data path's accepted input to the filter state of that sample: the
    angle block and the one-clock filter (parallel), or the bit-serial CORDIC with the
    bit-serial filter passes after each angle (serial)."""
    if variant == "serial":
        return SERIAL_DATAPATH_LATENCY
    return cordic_latency(variant) + 1


#: maximal-length Fibonacci LFSR taps (1-indexed bits, XOR feedback into bit 1), from Xilinx
#: XAPP052 "Efficient Shift Registers, LFSR Counters, and Long Pseudo-Random Sequence
#: Generators" table 3; :func:`lfsr_timer` checks the period it needs by stepping
LFSR_TAPS = {3: (3, 2), 4: (4, 3), 5: (5, 3), 6: (6, 5), 7: (7, 6), 8: (8, 6, 5, 4),
             9: (9, 5), 10: (10, 7), 11: (11, 9), 12: (12, 6, 4, 1), 13: (13, 4, 3, 1),
             14: (14, 5, 3, 1), 15: (15, 14), 16: (16, 15, 13, 4), 17: (17, 14),
             18: (18, 11), 19: (19, 6, 2, 1), 20: (20, 17)}


def lfsr_timer(period: int) -> tuple[int, tuple[int, ...], int, int]:
    """The serial chip's sample timer: ``(width, taps, seed, last)`` of the shortest LFSR
    (:data:`LFSR_TAPS`) whose sequence from ``seed = 1`` does not come back to the seed within
    ``period`` states; ``last`` is state ``period - 1``, after which the timer reloads the
    seed (so the period is exactly ``period`` clocks)."""
    period = validate.integer("lfsr_timer: period", period, 2)
    width = next((n for n in sorted(LFSR_TAPS) if (1 << n) - 1 >= period), None)
    if width is None:
        raise ValueError(f"lfsr_timer: period {period} is longer than the widest LFSR")
    taps, seed = LFSR_TAPS[width], 1
    state = seed
    for i in range(1, period):
        bit = 0
        for t in taps:
            bit ^= (state >> (t - 1)) & 1
        state = ((state << 1) | bit) & ((1 << width) - 1)
        if state == seed:
            raise ValueError(f"lfsr_timer: the {width}-bit LFSR repeats after {i} states")
    return width, taps, seed, state


def min_sample_period(spi_div: int, baud_div: int, variant: str = "parallel") -> int:
    """Shortest sample period for which a sample's packet is sent before the next starts."""
    UartPacketTx.check_parameters(PACKET_LEN, baud_div)  # (spi_div: spi_cycles checks it)
    return spi_cycles(spi_div) + datapath_latency(variant) + 7 + 10 * PACKET_LEN * baud_div


def timing(spi_div: int = DEFAULT_SPI_DIV, baud_div: int = BAUD_DIV_9600_AT_10MHZ,
           sample_period: int = DEFAULT_SAMPLE_PERIOD, clk_hz: int = CLK_HZ,
           variant: str = "parallel") -> dict:
    """Per-sample schedule in clocks (and seconds): SPI, latency from CS_N rising to the first
    start bit, packet time, busy time and the slack inside the sample period."""
    _check_chip(spi_div, baud_div, sample_period, variant)  # spi_div 0 divided by zero
    clk_hz = validate.integer("clk_hz", clk_hz, 1)
    spi = spi_cycles(spi_div)
    # the parallel chip registers the packet before its UART takes the first byte; the serial
    # chip's UART starts on the data path's valid output
    latency = spi_div + 1 + datapath_latency(variant) + (variant == "parallel")
    packet = 10 * PACKET_LEN * baud_div
    # start pulse is the cycle the timer is 0; CS_N falls 1 clock later; CS_N rises at
    # spi - spi_div (the end of the burst's hold phase, before the gap)
    cs_rise = spi - spi_div
    first_start = cs_rise + latency
    busy = first_start + packet
    return {
        "variant": variant, "clk_hz": clk_hz, "spi_div": spi_div, "baud_div": baud_div,
        "sample_period": sample_period, "spi_cycles": spi, "cs_rise_cycle": cs_rise,
        "latency_cs_rise_to_start_bit": latency, "packet_cycles": packet,
        "busy_cycles": busy, "slack_cycles": sample_period - busy,
        "slack_s": (sample_period - busy) / clk_hz, "baud": clk_hz / baud_div,
        "sclk_hz": clk_hz / (2 * spi_div),
    }


def _check_chip(spi_div, baud_div, sample_period, variant) -> None:
    """The chip's parameters (``ValueError`` naming the one that is wrong), checked before the
    chip or any of its blocks exists (:class:`~navgate.gateware.parameters.CheckedParameters`)."""
    cordic_latency(variant)
    Mpu6500Spi.check_parameters(spi_div, False, ())
    UartPacketTx.check_parameters(PACKET_LEN, baud_div)
    need = min_sample_period(spi_div, baud_div, variant)
    if not isinstance(sample_period, int) or sample_period < need:
        raise ValueError(f"TinyKalman: sample_period must be an integer >= {need} clocks "
                         f"for spi_div={spi_div}, baud_div={baud_div}; got {sample_period!r}")


class TinyKalmanCore(CheckedParameters, wiring.Component):
    """The chip's logic on plain pins, in the ``sync`` domain (reset active high)."""

    @classmethod
    def check_parameters(cls, spi_div, baud_div, sample_period, variant):
        _check_chip(spi_div, baud_div, sample_period, variant)

    def __init__(self, spi_div: int = DEFAULT_SPI_DIV, baud_div: int = BAUD_DIV_9600_AT_10MHZ,
                 sample_period: int = DEFAULT_SAMPLE_PERIOD, variant: str = "parallel"):
        self.variant = variant
        if variant == "serial":
            self.spi = Mpu6500Spi(spi_div, direct=True, external=("ay", "az", "gx", "gy"))
        else:
            self.spi = Mpu6500Spi(spi_div)
        self.uart = (UartPacketTx(PACKET_LEN, baud_div) if variant == "serial"
                     else UartTx(baud_div))
        self.spi_div, self.baud_div, self.sample_period = spi_div, baud_div, sample_period
        self.LATENCY = timing(spi_div, baud_div, sample_period,
                              variant=variant)["latency_cs_rise_to_start_bit"]
        self.THROUGHPUT = Fraction(1, sample_period)
        super().__init__({
            "miso": In(1),
            "mosi": Out(1),
            "sclk": Out(1, init=1),
            "cs_n": Out(1, init=1),
            "tx": Out(1, init=1),
            "fault": Out(1),
            "sat": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.spi = spi = self.spi
        serial = self.variant == "serial"
        if serial:
            m.submodules.datapath = datapath = TinyKalmanSerialDatapath(held_input=True,
                                                                         spi_fed=True)
            m.d.comb += [datapath.spi_bit.eq(spi.bit)]
            for name in spi.external:
                m.d.comb += getattr(datapath, f"shift_{name}").eq(getattr(spi, f"shift_{name}"))
            for name in ("gx", "gy"):
                m.d.comb += getattr(datapath, f"last_{name}").eq(getattr(spi, f"last_{name}"))
        else:
            m.submodules.datapath = datapath = TinyKalmanDatapath()
        m.submodules.uart = uart = self.uart

        sending = Signal()
        if serial:
            # the sample timer as a linear-feedback shift register (no incrementer): it starts
            # at the seed, steps, and goes back to the seed after sample_period states
            width, taps, seed, last = lfsr_timer(self.sample_period)
            timer = Signal(width, init=seed)
            feedback = timer[taps[0] - 1]
            for t in taps[1:]:
                feedback = feedback ^ timer[t - 1]
            m.d.sync += timer.eq(Mux(timer == last, seed, Cat(feedback, timer[:-1])))
            start = timer == seed
        else:
            timer = Signal(range(self.sample_period))
            m.d.sync += timer.eq(Mux(timer == self.sample_period - 1, 0, timer + 1))
            start = timer == 0
        m.d.comb += [
            spi.start.eq(start),
            spi.miso.eq(self.miso),
            self.mosi.eq(spi.mosi),
            self.sclk.eq(spi.sclk),
            self.cs_n.eq(spi.cs_n),
            self.tx.eq(uart.tx),
        ]
        # SPI -> datapath (CORDIC angles, filter); the WHO_AM_I check travels beside the words
        sp = spi.o.payload
        dp = datapath.i.payload
        m.d.comb += [
            dp.ax.eq(sp.ax), dp.ay.eq(sp.ay), dp.az.eq(sp.az), dp.gx.eq(sp.gx), dp.gy.eq(sp.gy),
            dp.ok.eq(sp.who_ok if serial else sp.who_am_i == WHO_AM_I_VALUE),
            datapath.i.valid.eq(spi.o.valid),
            spi.o.ready.eq(datapath.i.ready),
        ]
        if serial:
            # the flags change while the sample is computed, before its packet: fault when the
            # data path takes the sample, sat is the data path's own flag (set after roll)
            with m.If(datapath.i.valid & datapath.i.ready):
                m.d.sync += self.fault.eq(~dp.ok)
            m.d.comb += self.sat.eq(datapath.o.payload.sat)
        else:
            with m.If(datapath.o.valid & ~sending):
                m.d.sync += [self.fault.eq(~datapath.o.payload.ok),
                             self.sat.eq(datapath.o.payload.sat)]
        # filter -> packet -> UART
        if serial:
            # the serial chip sends the filter state itself (it holds until the next sample's
            # update, after this packet: sample_period >= min_sample_period), bit by bit
            roll, pitch = datapath.o.payload.roll, datapath.o.payload.pitch
            m.d.comb += [
                uart.packet.eq(Cat(Const(HEADER[0], 8), Const(HEADER[1], 8), roll[8:],
                                   roll[:8], pitch[8:], pitch[:8])),
                uart.start.eq(datapath.o.valid),
                sending.eq(uart.busy),
                datapath.o.ready.eq(~sending),
            ]
            return m
        index = Signal(range(PACKET_LEN))
        roll, pitch = Signal(16), Signal(16)
        packet = Array([Const(HEADER[0], 8), Const(HEADER[1], 8), roll[8:], roll[:8],
                        pitch[8:], pitch[:8]])
        m.d.comb += [
            datapath.o.ready.eq(~sending),
            uart.i.valid.eq(sending),
            uart.i.payload.eq(packet[index]),
        ]
        with m.If(datapath.o.valid & ~sending):
            m.d.sync += [roll.eq(datapath.o.payload.roll),
                         pitch.eq(datapath.o.payload.pitch), sending.eq(1), index.eq(0)]
        with m.If(sending & uart.i.ready):
            m.d.sync += index.eq(index + 1)
            with m.If(index == PACKET_LEN - 1):
                m.d.sync += sending.eq(0)
        return m


class TinyKalmanTop(CheckedParameters, wiring.Component):
    """TinyKalman as a TinyTapeout user module (seed 001 pinout), 10 MHz."""

    @classmethod
    def check_parameters(cls, spi_div, baud_div, sample_period, variant):
        _check_chip(spi_div, baud_div, sample_period, variant)

    def __init__(self, spi_div: int = DEFAULT_SPI_DIV, baud_div: int = BAUD_DIV_9600_AT_10MHZ,
                 sample_period: int = DEFAULT_SAMPLE_PERIOD, variant: str = "parallel"):
        self.core = TinyKalmanCore(spi_div, baud_div, sample_period, variant)
        self.params = {"spi_div": spi_div, "baud_div": baud_div, "sample_period": sample_period,
                       "variant": variant}
        self.LATENCY = self.core.LATENCY
        self.THROUGHPUT = self.core.THROUGHPUT
        super().__init__({
            "ui_in": In(8),
            "uo_out": Out(8),
            "uio_in": In(8),
            "uio_out": Out(8),
            "uio_oe": Out(8),
            "ena": In(1),
            "clk": In(1),
            "rst_n": In(1),
        })

    def elaborate(self, platform):
        m = Module()
        # the clock comes in as ``clk``; the reset is the active-low ``rst_n`` port
        m.domains.sync = ClockDomain("sync", reset_less=True)
        rst = Signal()
        m.d.comb += [ClockSignal("sync").eq(self.clk), rst.eq(~self.rst_n)]
        core = self.core
        m.submodules.core = ResetInserter(rst)(core)
        m.d.comb += [
            core.miso.eq(self.ui_in[0]),
            self.uo_out.eq(Cat(core.mosi, core.sclk, core.cs_n, core.tx, Const(0, 4))),
            self.uio_out.eq(Cat(core.fault, core.sat, Const(0, 6))),
            self.uio_oe.eq(0b0000_0011),
        ]
        return m


def TinyKalmanSerialTop(spi_div: int = DEFAULT_SPI_DIV, baud_div: int = BAUD_DIV_9600_AT_10MHZ,
                        sample_period: int = DEFAULT_SAMPLE_PERIOD) -> TinyKalmanTop:
    """The serial chip (block ``tinykalman_serial_top``): :class:`TinyKalmanTop` with the
    bit-serial CORDIC and filter (:mod:`navgate.systems.tinykalman.serial`), same pins and
    packets."""
    return TinyKalmanTop(spi_div, baud_div, sample_period, variant="serial")
