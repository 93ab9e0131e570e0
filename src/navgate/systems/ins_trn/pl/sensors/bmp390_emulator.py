"""BMP390 SPI slave emulator in gateware: a register image served over the SPI pins from a
stream of raw samples, with the INT pin as data ready, for FPGA co-simulation and
hardware-in-the-loop tests.

Reference: the BMP390 register map and SPI protocol as navgate.devices.bmp390 encodes them
(:class:`~navgate.devices.bmp390.Bmp390Model` is the bus-level Python model this emulator
matches byte for byte): SPI mode 3 (CPOL=1, CPHA=1), 8-bit words MSB first; a read is
``0x80 | addr``, one dummy byte (0x00), then the registers from ``addr`` on with
auto-increment (7-bit addresses, wrapping); a write is ``addr``, ``data`` byte pairs.
MISO reads 0xFF during the command byte and during a whole write (the model's choice).

Register image (the model's): CHIP_ID 0x60 (0x00), REV_ID 0x01 (0x01), ERR_REG 0 (0x02),
STATUS (0x03: cmd_rdy 0x10, plus drdy_press|drdy_temp 0x60 when a new sample is served),
DATA_0..5 (0x04..0x09: the current sample's pressure and temperature ADC words, 24 bits,
little-endian, :func:`~navgate.devices.bmp390.data_bytes`), PWR_CTRL, OSR, ODR, CONFIG,
INT_CTRL, IF_CONF (writable, read back, reset 0), CMD 0xB6 (soft reset: PWR_CTRL = 0), the
21-byte NVM at 0x31..0x45 (constructor parameter, default
``bmp390.nvm_bytes(DEFAULT_NVM)``); every other address reads 0. While the part is not in
normal mode with both sensors on (PWR_CTRL & 0x33 != 0x33) DATA_0..5 read the reset value
0x800000, STATUS reads 0x10, INT stays low and no sample is consumed.

Sample rule. Samples are pushed on ``samples`` into a :data:`FIFO_DEPTH` = 4 deep FIFO
(SyncFIFOBuffered; ``ready`` low while it is full: a producer faster than the master stalls,
nothing is lost). At the (detected) CS_N falling edge of every transaction the emulator
latches whether a sample is waiting (``have``) and, if so, the oldest one into the data
registers; otherwise the data registers keep the last sample (reset value 0x800000 before the
first). STATUS reads 0x70 if ``have``, else 0x10. The sample is **consumed** (popped,
counted in ``served``) at the detected CS_N rising edge of a *sample read*: a read that started
at an address <= 0x04 and clocked out the whole byte at 0x09 (DATA_5), and clocked out no
byte at or above 0x31 (the NVM; a start-up read 0x00..0x45 consumes nothing), in normal mode
- :class:`~navgate.devices.bmp390.Bmp390Model`'s rule. A sample read with ``have`` = 0 is an
**underrun** (``underruns``): STATUS without drdy and the previous sample's data, as a real
part between conversions; SpiMasterBaro rejects it (drdy check) and counts an error. Any other
transaction consumes nothing.

``int_pin`` (the BMP390 INT pin as data ready, active high, a registered level): high while a
sample is waiting, the part is in normal mode and no transaction is in progress; low from the
detected CS_N falling edge until one cycle after the detected CS_N rising edge. A master that
reads 0x00..0x09 at each rising edge of INT therefore reads every pushed sample exactly once,
in order: INT rises again after a sample read only if another sample is waiting, and after a
read that consumed nothing (the start-up read) it rises again for the same sample.

Pins and timing as :mod:`.adis16500_emulator`: ``sclk``, ``mosi``, ``cs_n`` are asynchronous,
each through a two-flip-flop synchroniser, edges detected on the synchronised levels
(:data:`PIN_DELAY` = 3 cycles); MOSI is sampled at the detected SCLK rising edge and MISO (a
registered output) moves to the next bit there, 3 cycles after the master's sampling edge. That
works for **SCLK half periods >= 3 cycles** (:data:`MIN_HALF` = spi_phy.MIN_HALF, the fastest
SCLK SpiMasterBaro generates: cfg_spi_div <= 2). ``miso`` is 1 (pull-up level) while CS_N is
high; ``miso_oe`` says when a real pin driver should drive it.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth.hdl import Cat, Const, Module, Signal, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from navgate.devices import bmp390

from .spi_phy import MIN_HALF as _MASTER_MIN_HALF
from .spi_phy import slave_pins

#: the samples' layout: raw 24-bit ADC words (uncompensated pressure and temperature)
SAMPLE_LAYOUT = data.StructLayout({"up": unsigned(24), "ut": unsigned(24)})
SYNC_STAGES = 2
#: cycles from a pin change to the emulator acting on it (synchroniser + edge register)
PIN_DELAY = SYNC_STAGES + 1
#: minimum SCLK half period (cycles) the emulator supports (= SpiMasterBaro's minimum)
MIN_HALF = 3
assert MIN_HALF == _MASTER_MIN_HALF
FIFO_DEPTH = 4
#: the data registers' reset value (DATA_0..2 and DATA_3..5 read 0x800000)
RESET_ADC = 0x800000
#: registers the model stores on a write (read back as written, reset 0)
WRITABLE = ("PWR_CTRL", "OSR", "ODR", "CONFIG", "INT_CTRL", "IF_CONF")
REV_ID = 0x01
SOFT_RESET = 0xB6
DRDY = bmp390.STATUS_DRDY_PRESS | bmp390.STATUS_DRDY_TEMP
DATA_LAST = 0x09
DATA_FIRST = 0x04


class Bmp390Emulator(wiring.Component):
    """BMP390 SPI slave (mode 3) fed by a raw-sample stream, with INT as data ready."""

    def __init__(self, nvm: bytes | None = None, fifo_depth: int = FIFO_DEPTH,
                 counter_bits: int = 32):
        nvm = bmp390.nvm_bytes(bmp390.DEFAULT_NVM) if nvm is None else bytes(nvm)
        if len(nvm) != bmp390.NVM_LEN:
            raise ValueError(f"BMP390 NVM image has {bmp390.NVM_LEN} bytes, got {len(nvm)}")
        self.nvm = nvm
        self.fifo_depth = fifo_depth
        #: cycles from the SCLK rising edge on the pin to the next MISO bit on the pin
        self.LATENCY = PIN_DELAY
        #: at most one sample read (12 bytes of 8 SCLK cycles of 2 x MIN_HALF) per sample
        self.THROUGHPUT = Fraction(1, (DATA_LAST + 3) * 8 * 2 * MIN_HALF)
        super().__init__({
            "sclk": In(1, init=1), "mosi": In(1), "cs_n": In(1, init=1),
            "miso": Out(1, init=1), "miso_oe": Out(1), "int_pin": Out(1),
            "samples": In(stream.Signature(SAMPLE_LAYOUT)),
            "served": Out(counter_bits), "underruns": Out(counter_bits),
        })

    def elaborate(self, platform):
        m = Module()
        mosi, sclk_rise, cs_fall, cs_rise = slave_pins(m, self.sclk, self.mosi, self.cs_n)

        m.submodules.fifo = fifo = SyncFIFOBuffered(width=SAMPLE_LAYOUT.size,
                                                    depth=self.fifo_depth)
        m.d.comb += [fifo.w_data.eq(self.samples.payload), fifo.w_en.eq(self.samples.valid),
                     self.samples.ready.eq(fifo.w_rdy)]

        # writable registers (the model's list) and the mode they set
        wregs = {name: Signal(8, name=f"r_{name.lower()}") for name in WRITABLE}
        normal = Signal()
        m.d.comb += normal.eq((wregs["PWR_CTRL"] & 0x33) == bmp390.PWR_CTRL_NORMAL)

        active = Signal()  # CS_N low (as detected)
        cur = Signal(SAMPLE_LAYOUT, init={"up": RESET_ADC, "ut": RESET_ADC})
        have = Signal()  # a sample was waiting at CS_N falling
        bit = Signal(3)
        nbyte = Signal(2)  # bytes completed, saturating at 2
        rx = Signal(8)
        is_read = Signal()
        start = Signal(7)  # a read's start address
        ptr = Signal(7)  # address of the next register byte to load
        waddr = Signal(7)
        wphase = Signal()  # write: 1 once the address byte is in
        saw_d5 = Signal()  # a read clocked out the byte at 0x09 (started <= 0x04)
        saw_nvm = Signal()  # a read clocked out a byte at or above 0x31
        sr = Signal(8)  # the byte being shifted out, MSB on MISO

        m.d.comb += [self.miso.eq(~active | sr[7]), self.miso_oe.eq(active)]
        m.d.sync += self.int_pin.eq(fifo.r_rdy & normal & ~active & ~cs_fall)

        # register read mux (address ptr)
        shown = Signal(SAMPLE_LAYOUT)
        m.d.comb += shown.eq(cur)
        with m.If(~normal):
            m.d.comb += [shown.up.eq(RESET_ADC), shown.ut.eq(RESET_ADC)]
        data_regs = Cat(shown.up, shown.ut)
        reg = Signal(8)
        with m.Switch(ptr):
            with m.Case(bmp390.REG["CHIP_ID"]):
                m.d.comb += reg.eq(bmp390.CHIP_ID)
            with m.Case(bmp390.REG["REV_ID"]):
                m.d.comb += reg.eq(REV_ID)
            with m.Case(bmp390.REG["STATUS"]):
                m.d.comb += reg.eq(bmp390.STATUS_CMD_RDY
                                   | Cat(Const(0, 5), (have & normal).replicate(2)))
            for k in range(6):
                with m.Case(DATA_FIRST + k):
                    m.d.comb += reg.eq(data_regs[8 * k:8 * k + 8])
            for name, s in wregs.items():
                with m.Case(bmp390.REG[name]):
                    m.d.comb += reg.eq(s)
            for k, b in enumerate(self.nvm):
                with m.Case(bmp390.NVM_ADDR + k):
                    m.d.comb += reg.eq(b)

        with m.If(cs_fall):
            m.d.sync += [active.eq(1), bit.eq(0), nbyte.eq(0), sr.eq(0xFF), is_read.eq(0),
                         wphase.eq(0), saw_d5.eq(0), saw_nvm.eq(0), have.eq(fifo.r_rdy)]
            with m.If(fifo.r_rdy):
                m.d.sync += cur.eq(fifo.r_data)
        with m.Elif(cs_rise):
            m.d.sync += active.eq(0)
            with m.If(is_read & saw_d5 & ~saw_nvm & normal):
                with m.If(have):
                    m.d.comb += fifo.r_en.eq(1)
                    m.d.sync += self.served.eq(self.served + 1)
                with m.Else():
                    m.d.sync += self.underruns.eq(self.underruns + 1)
        with m.Elif(active & sclk_rise):
            full = Cat(mosi, rx[:7])
            m.d.sync += [bit.eq(bit + 1), rx.eq(full), sr.eq(sr << 1)]
            with m.If(bit == 7):
                with m.If(nbyte != 2):
                    m.d.sync += nbyte.eq(nbyte + 1)
                with m.If(nbyte == 0):  # the command byte
                    with m.If(full[7]):
                        m.d.sync += [is_read.eq(1), start.eq(full[:7]), ptr.eq(full[:7]),
                                     sr.eq(0x00)]  # the dummy byte
                    with m.Else():
                        m.d.sync += [waddr.eq(full[:7]), wphase.eq(1), sr.eq(0xFF)]
                with m.Elif(is_read):
                    m.d.sync += [sr.eq(reg), ptr.eq(ptr + 1)]
                    with m.If(nbyte == 2):  # a register byte (at ptr - 1) completed
                        done_addr = (ptr - 1)[:7]
                        with m.If((done_addr == DATA_LAST) & (start <= DATA_FIRST)):
                            m.d.sync += saw_d5.eq(1)
                        with m.If(done_addr >= bmp390.NVM_ADDR):
                            m.d.sync += saw_nvm.eq(1)
                with m.Else():  # write: address, data, address, data ...
                    m.d.sync += sr.eq(0xFF)
                    with m.If(wphase == 0):
                        m.d.sync += [waddr.eq(full[:7]), wphase.eq(1)]
                    with m.Else():
                        m.d.sync += wphase.eq(0)
                        for name, s in wregs.items():
                            with m.If(waddr == bmp390.REG[name]):
                                m.d.sync += s.eq(full)
                        with m.If((waddr == bmp390.REG["CMD"]) & (full == SOFT_RESET)):
                            m.d.sync += wregs["PWR_CTRL"].eq(0)
        return m


#: INT rising (emulator pin) to CS_N falling in SpiMasterBaro's INT mode: master INT
#: synchroniser (2), edge -> fire (1), WAIT -> START (1), START -> CS_N low (1)
INT_TO_CS = 5
#: CS_N rising (master) to the next CS_N falling while samples are waiting: emulator CS_N
#: synchroniser + edge (3), INT register (1), then INT_TO_CS (measured in the tests: 9)
INT_ROUND_TRIP = PIN_DELAY + 1 + INT_TO_CS


class Bmp390Loopback(wiring.Component):
    """Emulator -> pins -> SpiMasterBaro (INT mode, cfg_spi_div ``div``) as one stream block
    (a test and co-simulation fixture for the verify harness): ``i`` = the emulator's samples,
    ``o`` = the master's raw (up, ut) (the NVM is checked in the Amaranth tests). ``o`` must be
    always ready (the master holds one sample; a second one would be an overrun)."""

    def __init__(self, div: int = MIN_HALF - 1):
        from .spi_master_baro import SAMPLE_LAST_ADDR, read_cycles

        self.div = div
        nbytes = SAMPLE_LAST_ADDR + 3
        #: INT rising to the sample out (621 cycles at cfg_spi_div 2; asserted in the tests)
        self.LATENCY = INT_TO_CS + read_cycles(div, nbytes) + 1
        #: samples waiting: one sample read + the INT round trip (624 cycles at div 2)
        self.THROUGHPUT = Fraction(1, read_cycles(div, nbytes) + INT_ROUND_TRIP)
        super().__init__({"i": In(stream.Signature(SAMPLE_LAYOUT)),
                          "o": Out(stream.Signature(SAMPLE_LAYOUT))})

    def elaborate(self, platform):
        from .spi_master_baro import SpiMasterBaro

        m = Module()
        m.submodules.emu = emu = Bmp390Emulator()
        m.submodules.master = mst = SpiMasterBaro(tick_cycles=1)
        m.d.comb += [emu.sclk.eq(mst.sclk), emu.mosi.eq(mst.mosi), emu.cs_n.eq(mst.cs_n),
                     mst.miso.eq(emu.miso), mst.int_pin.eq(emu.int_pin),
                     mst.cfg_int_sync.eq(1), mst.cfg_spi_div.eq(self.div),
                     self.o.payload.up.eq(mst.o.payload.up), self.o.payload.ut.eq(mst.o.payload.ut),
                     self.o.valid.eq(mst.o.valid), mst.o.ready.eq(self.o.ready)]
        wiring.connect(m, wiring.flipped(self.i), emu.samples)
        return m
