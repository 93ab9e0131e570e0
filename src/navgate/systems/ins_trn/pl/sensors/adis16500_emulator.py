"""ADIS16500 SPI slave emulator in gateware: serves burst reads (command 0x6800) from a stream
of samples, with a data-ready pin, for FPGA co-simulation and hardware-in-the-loop tests.

Reference: the ADIS16500 data sheet's burst read as navgate.devices.adis16500 encodes it
(:func:`~navgate.devices.adis16500.burst_words`): after the 16-bit command 0x6800 the part
shifts out ten words, DIAG_STAT, X/Y/Z_GYRO_OUT, X/Y/Z_ACCL_OUT, TEMP_OUT, DATA_CNTR and the
checksum (16-bit sum of the 18 bytes of the nine words before it), MSB first, SPI mode 3
(CPOL=1, CPHA=1: SCLK idles high, the master samples MISO on the rising edge). The data-ready
pin follows the data sheet's recommended use (burst after data ready), reduced to a level.

Pins and timing. ``sclk``, ``mosi`` and ``cs_n`` come from the master's pins and are treated
as asynchronous: each passes a two-flip-flop synchroniser (FFSynchronizer) and the edges are
detected on the synchronised levels, so every pin event is seen :data:`PIN_DELAY` = 3 cycles
after it happened, in order (the three pins have identical delays). MOSI is sampled at the
detected SCLK rising edge. MISO is a registered output and moves to the next bit at the
*detected rising* edge, i.e. 3 cycles after the master's sampling edge, not at the falling
edge: for a mode-3 master (which samples on the rising edge) the bit is then held 3 cycles
after its sampling edge and set up ``2 * half - 3`` cycles before the next one. Shifting at
the detected falling edge would need ``half >= 4`` for the master of this package (its own
MISO synchroniser samples the pin as it was at its rising edge); shifting after the rising
edge works at **half >= 3 cycles, the minimum SCLK half period** (:data:`MIN_HALF`, which is
``spi_phy.MIN_HALF``, the fastest SCLK ``SpiMasterImu`` generates: cfg_spi_div <= 2). The
emulator and the master may run on different clocks of similar frequency (one cycle more or
less of synchroniser delay): the hold time is then >= 2 emulator cycles.

Transaction. At CS_N falling the emulator pops the oldest waiting sample into its burst
register (or notes that none was waiting); it shifts out zeros during the command word. If the
command is 0x6800 it then shifts out the ten burst words of that sample, with DATA_CNTR = its
own count of served bursts (1 for the first, wrapping at 2**16; an underrun does not advance
it). Words clocked in after the command are ignored; clocks beyond the tenth word read 0.

* **Underrun** (a burst command with no sample waiting at CS_N falling): all ten words are 0,
  checksum included. SpiMasterImu rejects an all-zero burst and counts it as an error (it is
  also what a MISO stuck low returns); ``underruns`` counts them. Hence the one aliasing case:
  after 65,536 served bursts DATA_CNTR is 0, and a sample whose words are all 0 is then
  indistinguishable from an underrun and rejected by the master too.
* **Other commands** (register reads and writes) are not emulated: the transaction returns
  zeros and the sample popped at CS_N falling is dropped, counted in ``dropped``.
* A burst counts as served (``bursts``) when its command has been recognised, whether or not
  the master clocks all ten words out.

``dr`` (data ready, a registered level): high while a sample is waiting and no transaction is
in progress; low from the (detected) CS_N falling edge until one cycle after the detected CS_N
rising edge. A master that starts a burst at each rising edge of ``dr`` therefore reads every
sample exactly once: ``dr`` rises again after a burst only if more samples are waiting.

``samples`` is a stream (valid/ready) into a :data:`FIFO_DEPTH` = 4 deep FIFO (a
SyncFIFOBuffered: registered output). ``ready`` is low while the FIFO is full, so a producer
faster than the master stalls rather than losing samples. ``miso`` is 1 (the bus pull-up level)
while CS_N is high; ``miso_oe`` says when a real pin driver should drive it.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth.hdl import Cat, Module, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from navgate.devices import adis16500

from .spi_master_imu import SAMPLE_LAYOUT as MASTER_SAMPLE_LAYOUT
from .spi_master_imu import SpiMasterImu, burst_cycles
from .spi_phy import MIN_HALF as _MASTER_MIN_HALF
from .spi_phy import slave_pins

#: the samples' layout (int16 words as the part outputs them; DIAG_STAT unsigned)
SAMPLE_LAYOUT = data.StructLayout({
    "gx": signed(16), "gy": signed(16), "gz": signed(16),
    "ax": signed(16), "ay": signed(16), "az": signed(16),
    "temp": signed(16), "diag": unsigned(16),
})
#: burst word order (navgate.devices.adis16500.BURST_FIELDS) -> sample field
WORD_FIELDS = ("diag", "gx", "gy", "gz", "ax", "ay", "az", "temp")
SYNC_STAGES = 2
#: cycles from a pin change to the emulator acting on it (synchroniser + edge register)
PIN_DELAY = SYNC_STAGES + 1
#: minimum SCLK half period (cycles) the emulator supports (= SpiMasterImu's minimum)
MIN_HALF = 3
assert MIN_HALF == _MASTER_MIN_HALF
FIFO_DEPTH = 4
#: CS_N rising (master) to the next CS_N falling in SpiMasterImu's data-ready mode while
#: samples are waiting: emulator CS_N synchroniser + edge (3), DR register (1), master DR
#: synchroniser + edge (3), master FSM idle -> CS_N low (1)
DR_ROUND_TRIP = PIN_DELAY + 1 + 3 + 1


class Adis16500Emulator(wiring.Component):
    """ADIS16500 burst-read SPI slave (mode 3) fed by a sample stream, with data ready."""

    def __init__(self, fifo_depth: int = FIFO_DEPTH, counter_bits: int = 32):
        self.fifo_depth = fifo_depth
        #: cycles from the SCLK rising edge on the pin to the next MISO bit on the pin
        self.LATENCY = PIN_DELAY
        #: at most one burst per 11 x 16 SCLK cycles of MIN_HALF x 2 cycles
        self.THROUGHPUT = Fraction(1, (adis16500.BURST_WORDS + 1) * 16 * 2 * MIN_HALF)
        super().__init__({
            "sclk": In(1, init=1), "mosi": In(1), "cs_n": In(1, init=1),
            "miso": Out(1, init=1), "miso_oe": Out(1), "dr": Out(1),
            "samples": In(stream.Signature(SAMPLE_LAYOUT)),
            "bursts": Out(counter_bits), "underruns": Out(counter_bits),
            "dropped": Out(counter_bits),
        })

    def elaborate(self, platform):
        m = Module()
        mosi, sclk_rise, cs_fall, cs_rise = slave_pins(m, self.sclk, self.mosi, self.cs_n)

        m.submodules.fifo = fifo = SyncFIFOBuffered(width=SAMPLE_LAYOUT.size,
                                                    depth=self.fifo_depth)
        m.d.comb += [fifo.w_data.eq(self.samples.payload), fifo.w_en.eq(self.samples.valid),
                     self.samples.ready.eq(fifo.w_rdy)]

        active = Signal()  # CS_N low (as detected)
        cur = Signal(SAMPLE_LAYOUT)  # the sample of this transaction
        have = Signal()  # a sample was waiting at CS_N falling
        burst = Signal()  # the command was 0x6800
        bit = Signal(4)
        word = Signal(range(adis16500.BURST_WORDS + 2))  # words completed (0: in the command)
        cmd = Signal(16)
        sr = Signal(16)  # the word being shifted out, MSB on MISO
        csum = Signal(16)
        cntr = Signal(16)  # DATA_CNTR of the last served burst

        m.d.comb += [self.miso.eq(~active | sr[15]), self.miso_oe.eq(active)]
        m.d.sync += self.dr.eq(fifo.r_rdy & ~active & ~cs_fall)

        # the data word to load after `word` words have completed (word 0 .. 9 -> burst word)
        nxt = Signal(16)
        with m.Switch(word):
            for k, name in enumerate(WORD_FIELDS):
                with m.Case(k):
                    m.d.comb += nxt.eq(getattr(cur, name))
            with m.Case(len(WORD_FIELDS)):
                m.d.comb += nxt.eq(cntr)
            with m.Case(len(WORD_FIELDS) + 1):
                m.d.comb += nxt.eq(csum)
        load = Signal(16)
        m.d.comb += load.eq(nxt & (have & burst).replicate(16))

        with m.If(cs_fall):
            m.d.sync += [active.eq(1), bit.eq(0), word.eq(0), sr.eq(0), csum.eq(0),
                         burst.eq(0), have.eq(fifo.r_rdy)]
            with m.If(fifo.r_rdy):
                m.d.comb += fifo.r_en.eq(1)
                m.d.sync += cur.eq(fifo.r_data)
        with m.Elif(cs_rise):
            m.d.sync += active.eq(0)
        with m.Elif(active & sclk_rise):
            full_cmd = Cat(mosi, cmd[:15])
            m.d.sync += [bit.eq(bit + 1), cmd.eq(full_cmd), sr.eq(sr << 1)]
            with m.If(bit == 15):
                with m.If(word == 0):
                    is_burst = full_cmd == adis16500.BURST_CMD
                    m.d.sync += [burst.eq(is_burst), word.eq(1)]
                    with m.If(is_burst & have):
                        # first burst word (DIAG_STAT) now; DATA_CNTR advances
                        m.d.sync += [self.bursts.eq(self.bursts + 1), cntr.eq(cntr + 1),
                                     sr.eq(cur.diag), csum.eq(cur.diag[:8] + cur.diag[8:])]
                    with m.Elif(is_burst):
                        m.d.sync += [self.underruns.eq(self.underruns + 1), sr.eq(0)]
                    with m.Else():
                        m.d.sync += sr.eq(0)
                        with m.If(have):
                            m.d.sync += self.dropped.eq(self.dropped + 1)
                with m.Elif(word <= adis16500.BURST_WORDS):
                    m.d.sync += [word.eq(word + 1), sr.eq(load),
                                 csum.eq(csum + load[:8] + load[8:])]
        return m


class Adis16500Loopback(wiring.Component):
    """Emulator -> pins -> SpiMasterImu (DR mode, cfg_spi_div ``div``) as one stream block
    (a test and co-simulation fixture for the verify harness): ``i`` = the emulator's
    samples, ``o`` = the master's FIFO output (spi_master_imu.SAMPLE_LAYOUT)."""

    def __init__(self, div: int = MIN_HALF - 1):
        self.div = div
        #: CS_N falling to the sample out (1,094 at cfg_spi_div 2; asserted in the tests)
        self.LATENCY = burst_cycles(div) + 2
        #: samples waiting: one per burst + DR round trip (1,100 cycles at cfg_spi_div 2)
        self.THROUGHPUT = Fraction(1, burst_cycles(div) + DR_ROUND_TRIP)
        super().__init__({"i": In(stream.Signature(SAMPLE_LAYOUT)),
                          "o": Out(stream.Signature(MASTER_SAMPLE_LAYOUT))})

    def elaborate(self, platform):
        m = Module()
        m.submodules.emu = emu = Adis16500Emulator()
        m.submodules.master = mst = SpiMasterImu(tick_cycles=1)
        m.d.comb += [emu.sclk.eq(mst.sclk), emu.mosi.eq(mst.mosi), emu.cs_n.eq(mst.cs_n),
                     mst.miso.eq(emu.miso), mst.dr.eq(emu.dr), mst.cfg_dr_sync.eq(1),
                     mst.cfg_spi_div.eq(self.div)]
        wiring.connect(m, wiring.flipped(self.i), emu.samples)
        wiring.connect(m, mst.o, wiring.flipped(self.o))
        return m
