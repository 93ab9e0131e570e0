"""Seed 000 ``spi_master_baro``: BMP390 reader (SPI mode 3, 8-bit).

After reset (and after any failed start-up) it writes PWR_CTRL = 0x33 (normal mode, pressure
and temperature enabled) and reads registers 0x00..0x45 in one transfer: CHIP_ID, and the
21-byte calibration NVM (0x31..0x45), kept in ``nvm`` once the chip id reads 0x60. Then every
sample period it reads 0x00..0x09 (CHIP_ID, ERR_REG, STATUS, DATA_0..5) and delivers the raw
24-bit pressure and temperature with the NVM on ``o`` - the input layout of
``baro_compensation`` - if the chip id is 0x60 and STATUS has both drdy bits. Anything else (a
MISO stuck low or high, a missing device) is counted in ``error_count`` and raises
``sensor_error`` until the next good sample; a sample not taken from ``o`` before the next one
is an overrun (counted as an error).

SPI reads send 0x80 | address, then the part returns one dummy byte before the data
(data sheet, SPI interface). Configuration: ``cfg_spi_div`` (BARO_CFG[7:0], SCLK half period
= div + 1 cycles; 5 -> 8.3 MHz at 100 MHz, limit 10 MHz), ``cfg_enable`` (BARO_CFG[8]) and
``cfg_rate`` (sample period in ticks, default 40,000 us = 25 Hz; a navgate extension of the
register map, BARO_RATE). MISO passes a two-flip-flop synchroniser in the PHY path.

INT-paced mode (navgate extension, ``cfg_int_sync`` = BARO_CFG[9], default 0): a sample read
starts at each rising edge of the ``int_pin`` input (the BMP390's INT pin used as data ready,
asynchronous, through a two-flip-flop synchroniser) and the BARO_RATE timer no longer starts
sample reads. As in spi_master_imu's data-ready mode, the edge is that of INT gated by
``cfg_int_sync`` and ``cfg_enable``, so that switching the mode on while INT is already high
(a sample waiting) also starts a read. The start-up sequence (PWR_CTRL write, NVM read) is
unchanged, except that an INT edge seen during it is dropped at its end (the emulator, and a
part whose INT means "unread sample waiting", raise INT again after the start-up read, which
consumes no sample; keeping the early edge would start a second read of the same sample,
found in the tests); while the NVM is not valid (a failed start-up) the timer keeps pacing
the start-up retries in this mode too, since a missing part never raises INT. With
``cfg_int_sync`` = 0 ``int_pin`` is ignored and everything is as above.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth.hdl import Cat, Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.wiring import In, Out

from navgate.devices import bmp390

from .baro_compensation import IN_LAYOUT
from .spi_phy import MIN_HALF, SpiPhy, ready_edge, sample_timer

DEFAULT_DIV = 5
DEFAULT_RATE = 40000
INIT_LAST_ADDR = bmp390.NVM_ADDR + bmp390.NVM_LEN - 1  # 0x45
SAMPLE_LAST_ADDR = 0x09


def read_cycles(div: int, nbytes: int) -> int:
    """Cycles from CS_N falling to CS_N rising for an ``nbytes``-byte transfer."""
    half = max(div + 1, MIN_HALF)
    return half * (1 + nbytes * 17)


class SpiMasterBaro(wiring.Component):
    """BMP390 reader: power-up write, NVM read once, periodic data reads (seed 000)."""

    def __init__(self, tick_cycles: int = 100, counter_bits: int = 32):
        self.tick_cycles = tick_cycles
        #: cycles from CS_N falling (sample read) to ``o.valid``, default configuration
        self.LATENCY = read_cycles(DEFAULT_DIV, SAMPLE_LAST_ADDR + 3) + 1
        self.THROUGHPUT = Fraction(1, DEFAULT_RATE * tick_cycles)
        super().__init__({
            "sclk": Out(1, init=1), "mosi": Out(1), "miso": In(1, init=1),
            "cs_n": Out(1, init=1),
            "cfg_spi_div": In(8, init=DEFAULT_DIV), "cfg_enable": In(1, init=1),
            "cfg_rate": In(16, init=DEFAULT_RATE), "int_pin": In(1), "cfg_int_sync": In(1),
            "o": Out(stream.Signature(IN_LAYOUT)),
            "nvm_valid": Out(1), "sensor_error": Out(1),
            "sample_count": Out(counter_bits), "error_count": Out(counter_bits),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.phy = phy = SpiPhy(8)
        miso = Signal(init=1)
        m.submodules.miso_sync = FFSynchronizer(self.miso, miso, init=1, stages=2)
        m.d.comb += [phy.miso.eq(miso), phy.half.eq(self.cfg_spi_div + 1),
                     self.sclk.eq(phy.sclk), self.mosi.eq(phy.mosi)]

        fire = Signal()
        with m.If(sample_timer(m, self.tick_cycles, self.cfg_rate)):
            # INT mode: the timer only paces start-up retries (see the module docstring)
            m.d.sync += fire.eq(self.cfg_enable & (~self.cfg_int_sync | ~self.nvm_valid))

        nvm = Signal(8 * bmp390.NVM_LEN)
        data_sr = Signal(48)
        chip = Signal(8)
        status = Signal(8)
        idx = Signal(8)  # byte index within the transfer
        addr = Signal(8)
        m.d.comb += addr.eq(idx - 2)
        last = Signal(8)  # index of the last byte of this transfer
        init = Signal()  # 1: the start-up transfer (NVM), 0: a sample
        cnt = Signal(8)
        with m.If(self.o.valid & self.o.ready):
            m.d.sync += self.o.valid.eq(0)

        def fail():
            m.d.sync += [self.error_count.eq(self.error_count + 1), self.sensor_error.eq(1)]

        with m.FSM(name="baro"):
            with m.State("RESET"):
                with m.If(self.cfg_enable):
                    m.d.sync += [self.cs_n.eq(0), cnt.eq(0), idx.eq(0)]
                    m.next = "W_SETUP"
            with m.State("W_SETUP"):
                m.d.sync += cnt.eq(cnt + 1)
                with m.If(cnt >= self.cfg_spi_div):
                    m.d.comb += [phy.start.eq(1), phy.tx.eq(bmp390.REG["PWR_CTRL"])]
                    m.next = "W_XFER"
            with m.State("W_XFER"):
                with m.If(phy.done):
                    m.d.sync += idx.eq(idx + 1)
                    with m.If(idx == 0):
                        m.d.comb += [phy.start.eq(1), phy.tx.eq(bmp390.PWR_CTRL_NORMAL)]
                    with m.Else():
                        m.d.sync += [self.cs_n.eq(1), cnt.eq(0)]
                        m.next = "W_GAP"
            with m.State("W_GAP"):  # CS high for a half period, then the NVM read
                m.d.sync += cnt.eq(cnt + 1)
                with m.If(cnt >= self.cfg_spi_div):
                    m.d.sync += [init.eq(1), last.eq(INIT_LAST_ADDR + 2)]
                    m.next = "START"
            with m.State("WAIT"):
                with m.If(fire):
                    m.d.sync += fire.eq(0)
                    with m.If(self.nvm_valid):
                        m.d.sync += [init.eq(0), last.eq(SAMPLE_LAST_ADDR + 2)]
                        m.next = "START"
                    with m.Else():
                        m.next = "RESET"
            with m.State("START"):
                m.d.sync += [self.cs_n.eq(0), cnt.eq(0), idx.eq(0)]
                m.next = "R_SETUP"
            with m.State("R_SETUP"):
                m.d.sync += cnt.eq(cnt + 1)
                with m.If(cnt >= self.cfg_spi_div):
                    m.d.comb += [phy.start.eq(1), phy.tx.eq(0x80)]  # read from 0x00
                    m.next = "R_XFER"
            with m.State("R_XFER"):
                with m.If(phy.done):
                    m.d.sync += idx.eq(idx + 1)
                    with m.If(addr == 0):
                        m.d.sync += chip.eq(phy.rx)
                    with m.If(addr == 3):
                        m.d.sync += status.eq(phy.rx)
                    with m.If((addr >= 4) & (addr <= 9)):
                        m.d.sync += data_sr.eq(Cat(data_sr[8:], phy.rx))
                    with m.If(init & (addr >= bmp390.NVM_ADDR) & (addr <= INIT_LAST_ADDR)):
                        m.d.sync += nvm.eq(Cat(nvm[8:], phy.rx))
                    with m.If(idx == last):
                        m.d.sync += self.cs_n.eq(1)
                        m.next = "CHECK"
                    with m.Else():
                        m.d.comb += [phy.start.eq(1), phy.tx.eq(0)]
            with m.State("CHECK"):
                chip_ok = chip == bmp390.CHIP_ID
                drdy = bmp390.STATUS_DRDY_PRESS | bmp390.STATUS_DRDY_TEMP
                with m.If(init):
                    # INT mode: an INT edge seen during the start-up is dropped here; the
                    # part raises INT again after the start-up read if a sample is waiting
                    # (that read consumes none), so keeping it would read one sample twice
                    with m.If(self.cfg_int_sync):
                        m.d.sync += fire.eq(0)
                    with m.If(chip_ok):
                        m.d.sync += self.nvm_valid.eq(1)
                    with m.Else():
                        fail()
                with m.Elif(chip_ok & ((status & drdy) == drdy)):
                    with m.If(self.o.valid & ~self.o.ready):
                        fail()  # overrun: the previous sample was not taken
                    with m.Else():
                        m.d.sync += [self.o.valid.eq(1), self.o.payload.up.eq(data_sr[0:24]),
                                     self.o.payload.ut.eq(data_sr[24:48]),
                                     self.o.payload.nvm.eq(nvm),
                                     self.sample_count.eq(self.sample_count + 1),
                                     self.sensor_error.eq(0)]
                with m.Else():
                    fail()
                m.next = "WAIT"

        # INT mode: a sample read per rising edge of the synchronised INT (after the FSM so
        # that an edge in the cycle a read starts is kept for the next read), taken of INT
        # gated by the mode bits (switching the mode on while INT is high starts a read)
        with m.If(ready_edge(m, self.int_pin, self.cfg_int_sync, self.cfg_enable, name="int")):
            m.d.sync += fire.eq(1)
        return m
