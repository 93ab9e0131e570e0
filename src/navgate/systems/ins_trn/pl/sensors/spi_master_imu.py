"""Seed 000 ``spi_master_imu``: ADIS16500 burst reader (timer, assert CS, command, read words,
release), with output FIFO, ``sensor_error`` and sample/error counters.

Follows the seed's FSM with the data sheet's burst (navgate.devices.adis16500): the command
0x6800 is followed by ten words (DIAG_STAT, gyro x/y/z, accel x/y/z, TEMP_OUT, DATA_CNTR,
checksum), 176 SCLK cycles in all. A burst is delivered (pushed into the FIFO) only if the
checksum (16-bit sum of the 18 bytes before it) matches and the words are not all zero (an
all-zero burst, checksum included, is what a MISO stuck low or a missing pull-down device
returns, and its checksum is trivially right). Otherwise ``error_count`` counts it and
``sensor_error`` goes high until the next good burst; a full FIFO also counts as an error
(the sample is lost).

Configuration (seed AXI map): ``cfg_spi_div`` (IMU_CFG[7:0]: SCLK half period = div + 1
cycles; 49 -> 1 MHz at 100 MHz, the data sheet's burst maximum), ``cfg_enable`` (IMU_CFG[8]),
``cfg_rate`` (UPDATE_RATE[15:0]: sample period in ticks of ``tick_cycles`` clock cycles;
2500 ticks of 1 us = 2.5 ms, 400 Hz). The chip-select setup before the first SCLK edge is one
half period (>= the data sheet's 200 ns for any SCLK up to 2.5 MHz); the chip select stays high
between bursts for the rest of the sample period, which must be >= tSTALL (16 us) - true for
any UPDATE_RATE above the 176 us burst + 16 us at 1 MHz.

Data-ready mode (navgate extension, ``cfg_dr_sync`` = IMU_CFG[9], default 0): a burst starts
at each rising edge of the ``dr`` pin (the ADIS16500's DR output; the data sheet recommends
reading the burst after data ready) and the UPDATE_RATE timer is unused. The edge is that of
DR gated by ``cfg_dr_sync`` and ``cfg_enable``: turning the mode on while DR is high also
starts one burst (a level-DR source holding samples would otherwise never produce an edge).
With ``cfg_dr_sync`` = 0 the ``dr`` pin is ignored and everything is as above.

Clock domains: everything runs in ``sync`` (seed: clk_sys, 100 MHz); MISO and DR are the
asynchronous inputs and each passes a two-flip-flop synchroniser (MISO inside the PHY path).
"""

from __future__ import annotations

from fractions import Fraction

from amaranth.hdl import Cat, Module, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from navgate.devices import adis16500

from .spi_phy import MIN_HALF, SpiPhy, ready_edge, sample_timer

SAMPLE_LAYOUT = data.StructLayout({
    "diag": unsigned(16), "gx": signed(16), "gy": signed(16), "gz": signed(16),
    "ax": signed(16), "ay": signed(16), "az": signed(16), "temp": signed(16),
    "cntr": unsigned(16),
})
DEFAULT_DIV = 49  # 1 MHz SCLK at 100 MHz
DEFAULT_RATE = 2500  # ticks of 1 us: 400 Hz


def burst_cycles(div: int) -> int:
    """Cycles from CS_N falling to CS_N rising for SCLK half period ``div + 1`` cycles."""
    half = max(div + 1, MIN_HALF)
    return half * (1 + (adis16500.BURST_WORDS + 1) * 33)


#: LATENCY of the default configuration (see SpiMasterImu)
BURST_LATENCY = burst_cycles(DEFAULT_DIV) + 2


class SpiMasterImu(wiring.Component):
    """ADIS16500 burst reader: SPI mode 3, checksum, 16-deep FIFO, counters (seed 000)."""

    def __init__(self, tick_cycles: int = 100, fifo_depth: int = 16, counter_bits: int = 32):
        self.tick_cycles = tick_cycles
        self.fifo_depth = fifo_depth
        #: cycles from CS_N falling to the sample in the FIFO's output, default configuration:
        #: CS setup (one half period), 11 words of 33 half periods (16 SCLK cycles + tail),
        #: then the check cycle and the FIFO write (measured in the tests)
        self.LATENCY = BURST_LATENCY
        #: one sample per UPDATE_RATE ticks
        self.THROUGHPUT = Fraction(1, DEFAULT_RATE * tick_cycles)
        super().__init__({
            "sclk": Out(1, init=1), "mosi": Out(1), "miso": In(1, init=1),
            "cs_n": Out(1, init=1),
            "cfg_spi_div": In(8, init=DEFAULT_DIV), "cfg_enable": In(1, init=1),
            "cfg_rate": In(16, init=DEFAULT_RATE), "dr": In(1), "cfg_dr_sync": In(1),
            "o": Out(stream.Signature(SAMPLE_LAYOUT)),
            "sensor_error": Out(1), "sample_count": Out(counter_bits),
            "error_count": Out(counter_bits),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.phy = phy = SpiPhy(16)
        miso = Signal(init=1)
        m.submodules.miso_sync = FFSynchronizer(self.miso, miso, init=1, stages=2)
        m.d.comb += [phy.miso.eq(miso), phy.half.eq(self.cfg_spi_div + 1),
                     self.sclk.eq(phy.sclk), self.mosi.eq(phy.mosi)]
        width = SAMPLE_LAYOUT.size
        m.submodules.fifo = fifo = SyncFIFOBuffered(width=width, depth=self.fifo_depth)
        m.d.comb += [self.o.payload.eq(fifo.r_data), self.o.valid.eq(fifo.r_rdy),
                     fifo.r_en.eq(self.o.ready)]

        # sample timer: ticks of tick_cycles cycles, a burst every cfg_rate ticks
        fire = Signal()
        with m.If(sample_timer(m, self.tick_cycles, self.cfg_rate)):
            m.d.sync += fire.eq(self.cfg_enable & ~self.cfg_dr_sync)

        nwords = adis16500.BURST_WORDS
        word = Signal(range(nwords + 2))
        data_sr = Signal(width)  # words 1..9 (DIAG .. DATA_CNTR), shifted in
        csum = Signal(16)
        nonzero = Signal()
        cnt = Signal(8)
        with m.FSM(name="burst"):
            with m.State("IDLE"):
                with m.If(fire):
                    m.d.sync += [fire.eq(0), self.cs_n.eq(0), cnt.eq(0), word.eq(0),
                                 csum.eq(0), nonzero.eq(0)]
                    m.next = "CS_SETUP"
            with m.State("CS_SETUP"):
                m.d.sync += cnt.eq(cnt + 1)
                with m.If(cnt >= self.cfg_spi_div):
                    m.d.comb += [phy.start.eq(1), phy.tx.eq(adis16500.BURST_CMD)]
                    m.next = "XFER"
            with m.State("XFER"):
                with m.If(phy.done):
                    m.d.sync += word.eq(word + 1)
                    with m.If(word >= 1):
                        m.d.sync += nonzero.eq(nonzero | (phy.rx != 0))
                    with m.If((word >= 1) & (word <= nwords - 1)):
                        m.d.sync += [data_sr.eq(Cat(data_sr[16:], phy.rx)),
                                     csum.eq(csum + phy.rx[:8] + phy.rx[8:])]
                    with m.If(word == nwords):
                        m.d.sync += self.cs_n.eq(1)
                        m.next = "CHECK"
                    with m.Else():
                        m.d.comb += [phy.start.eq(1), phy.tx.eq(0)]
            with m.State("CHECK"):
                good = Signal()
                m.d.comb += good.eq((csum == phy.rx) & nonzero)
                with m.If(good & fifo.w_rdy):
                    m.d.comb += [fifo.w_en.eq(1), fifo.w_data.eq(data_sr)]
                    m.d.sync += [self.sample_count.eq(self.sample_count + 1),
                                 self.sensor_error.eq(0)]
                with m.Else():
                    m.d.sync += [self.error_count.eq(self.error_count + 1),
                                 self.sensor_error.eq(1)]
                m.next = "IDLE"

        # data-ready mode: a burst per rising edge of the synchronised DR (after the FSM so
        # that an edge in the cycle a burst starts is kept for the next burst). The edge is
        # taken of DR gated by the mode bits, so that switching the mode on while DR is
        # already high (samples waiting) also starts a burst.
        with m.If(ready_edge(m, self.dr, self.cfg_dr_sync, self.cfg_enable, name="dr")):
            m.d.sync += fire.eq(1)
        return m
