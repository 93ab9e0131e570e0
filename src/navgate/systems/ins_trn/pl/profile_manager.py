"""Seed 000 ``altitude_profile_manager``: the 64-entry profile FIFO and its DMA engine.

Seed 000 "Altitude Profile Buffer": terrain samples (``h_terrain = h_baro - h_agl``) with the
INS position and a time stamp, 128 bits per entry, in a 64-deep circular buffer; a DMA engine
that bursts the profile to DDR when the PS asks (registers PROF_CTRL, PROF_ADDR, PROF_COUNT,
PROF_STATUS of docs/seed000-registers.md).

Entry layout (:data:`PROFILE_ENTRY`, little-endian in memory, one entry = four 32-bit words):

    word 0  h_terrain   float32, m
    word 1  pos_n       float32, m (NED about the reference point)
    word 2  pos_e       float32, m
    word 3  time[23:0]  IMU samples propagated (ENG_STATUS.propagations; wraps after
                        11.6 h at 400 Hz), valid[24], reserved[31:25] = 0

:class:`TimestampCorrelator` (the seed's ``timestamp_correlator``) pairs each ranger frame
with the INS position and the time at its arrival; in ``ins_trn_top`` an entry is the PS's
terrain height (PROF_ENTRY_H) with the correlator's position and time (PROF_SAMPLE_*). The
time stamp counts IMU samples rather than milliseconds: a flight's result must not depend on
the hardware timer (the co-simulation compresses idle time between samples), and the sample
count is the time base the navigation state is referenced to (t = t0 + k dt, exactly the
record's time stamp). The validity checks and the terrain-height arithmetic happen on the PS
(the navigator's profile checks, docs/seed000-top.md); the FIFO stores what it is given.

Storage: one RAMB18E1 (half a BRAM36), 256 words of 32 bits in simple dual port, entry k in
words 4k..4k+3: the block RAM's word is the AXI write beat, so the DMA reads one word per
beat. An accepted entry writes word 0 in the cycle it is taken and words 1-3 (held in a
96-bit register) in the next three, during which ``entry.ready`` is low: one entry every
four cycles, where pushes come at 10 Hz. The read port is synchronous: the DMA addresses it
with the next word's address and enables it only when the W channel takes a beat, so the
word on W holds through back-pressure and the next one is there the cycle after; W is never
idle inside a burst. (The former 64 x 128 memory mapped to 43 RAM64M of LUT RAM, 172 LUTs.
Yosys maps the 256 x 32 one to the RAMB18E1 by itself; ``ram_style = "block"`` states it.)

DMA: a start pulse (PROF_CTRL.start) snapshots the newest ``min(PROF_COUNT, fill)`` entries
and writes them oldest first, contiguously from PROF_ADDR (16-byte aligned), over an AXI4
write master in legal Zynq HP-port bursts (:class:`navgate.gateware.axi4.AxiBurstWriter`).
The FIFO is not consumed: the PS reads the current window whenever it correlates. Entries keep
arriving during a DMA; if one lands in a slot the DMA has not read yet (possible only when the
snapshot is the whole buffer and a push arrives within the first microseconds, or in the
very cycle of the start), the ``overrun`` flag is raised with ``done`` so the PS can discard
the transfer. ``done`` pulses at the end (for the update interrupt), with ``error`` on a bus
error or overrun.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth import C, Cat, Module, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware.axi4 import AxiBurstWriter, axi4_write_signature

DEPTH = 64
ENTRY_WORDS = 4  #: 32-bit words per entry, the AXI write beat

PROFILE_ENTRY = data.StructLayout({
    "h_terrain": 32, "pos_n": 32, "pos_e": 32, "time": 24, "valid": 1, "reserved": 7,
})


def pack_entry(h_terrain: int, pos_n: int, pos_e: int, time: int, valid: int) -> int:
    """The 128-bit entry (float32 fields as bit patterns) as an integer, word 0 lowest."""
    return (h_terrain | pos_n << 32 | pos_e << 64 | (time & 0xFFFFFF) << 96
            | (valid & 1) << 120)


class TimestampCorrelator(wiring.Component):
    """Seed 000 ``timestamp_correlator``: on each ranger ``frame`` pulse, latches the INS
    position (the state's ``pN``/``pE`` words) and the time (IMU samples propagated) at that
    moment into ``sample_n``/``sample_e``/``sample_t``, which the next profile entry carries."""

    LATENCY = 1  #: frame -> latched sample
    THROUGHPUT = 1

    def __init__(self):
        super().__init__({
            "frame": In(1), "pos_n": In(32), "pos_e": In(32), "samples": In(24),
            "sample_n": Out(32), "sample_e": Out(32), "sample_t": Out(24),
        })

    def elaborate(self, platform):
        m = Module()
        with m.If(self.frame):
            m.d.sync += [self.sample_n.eq(self.pos_n), self.sample_e.eq(self.pos_e),
                         self.sample_t.eq(self.samples)]
        return m


class AltitudeProfileManager(wiring.Component):
    """Profile FIFO (64 x 128 bit in one RAMB18E1, 256 x 32) with an AXI4 burst DMA to memory.

    ``entry`` is a stream: an accepted entry takes the write port for four cycles (one word a
    cycle, word 0 in the cycle it is accepted), and ``entry.ready`` is low for the three
    cycles after it. It is counted in ``fill`` the cycle after it is accepted, as before, and
    a DMA started from then on includes it: the DMA reads that entry last, after its words
    are written.
    """

    LATENCY = 1  #: an accepted entry is counted in ``fill`` one cycle later
    #: entries per cycle: one every four cycles (``entry.ready`` low for three after each)
    THROUGHPUT = Fraction(1, ENTRY_WORDS)

    def __init__(self):
        super().__init__({
            "entry": In(stream.Signature(PROFILE_ENTRY)),
            "dma_start": In(1), "dma_address": In(32), "dma_count": In(8),
            "fill": Out(7), "busy": Out(1), "done": Out(1), "error": Out(1),
            "overrun": Out(1),
            "axi": Out(axi4_write_signature()),
        })

    def elaborate(self, platform):
        m = Module()
        # 256 x 32, one RAMB18E1: entry k holds words 4k..4k+3 (the words the DMA sends, in
        # order)
        m.submodules.memory = memory = Memory(shape=32, depth=DEPTH * ENTRY_WORDS, init=[],
                                              attrs={"ram_style": "block"})
        write = memory.write_port()
        read = memory.read_port()  # synchronous (block RAM): data one cycle after addr/en
        m.submodules.writer = writer = AxiBurstWriter(count_width=9)
        wiring.connect(m, wiring.flipped(self.axi), writer.axi)

        # ---------------------------------------------------------------- push
        w_ptr = Signal(6)  # the slot the next entry goes to
        fill = Signal(7)
        tail = Signal(2)  # word 1-3 of the last entry being written; 0: ready for the next
        upper = Signal(96)  # words 1-3 of that entry, held while they are written
        accept = Signal()
        payload = self.entry.payload.as_value()
        m.d.comb += [self.entry.ready.eq(tail == 0), accept.eq(self.entry.valid & (tail == 0)),
                     self.fill.eq(fill),
                     # word 0 from the stream as it is accepted (tail = 0), then words 1-3
                     write.data.eq(Cat(payload[:32], upper).word_select(tail, 32)),
                     write.addr.eq(Cat(tail, w_ptr - (tail != 0))),
                     write.en.eq(accept | (tail != 0))]
        with m.If(accept):
            m.d.sync += [upper.eq(payload[32:]), tail.eq(1), w_ptr.eq(w_ptr + 1)]
            with m.If(fill < DEPTH):
                m.d.sync += fill.eq(fill + 1)
        with m.Elif(tail != 0):
            m.d.sync += tail.eq(tail + 1)  # 3 -> 0

        # ---------------------------------------------------------------- DMA
        at = Signal(8)  # the word on the W channel (read.data): entry at[2:], word at[:2]
        rd_ptr = at[2:]
        pending = Signal(7)  # entries of the snapshot not yet fully handed to the writer
        overrun = Signal()
        starting = Signal()  # a DMA starts this cycle
        sent = Signal()  # the writer takes the word on W this cycle
        n = Signal(7)
        m.d.comb += n.eq(self.dma_count)
        with m.If(fill < self.dma_count):
            m.d.comb += n.eq(fill)
        # the read port is addressed with the next value of ``at``, and enabled only when
        # ``at`` moves: read.data is mem[at] the cycle after, and holds while W stalls
        at_next = Signal(8)
        m.d.comb += [at_next.eq(at), writer.data.payload.eq(read.data),
                     read.addr.eq(at_next), read.en.eq(starting | sent)]
        with m.If(starting):
            m.d.comb += at_next.eq(Cat(C(0, 2), w_ptr - n))
        with m.Elif(sent):
            m.d.comb += at_next.eq(at + 1)
        m.d.sync += at.eq(at_next)
        m.d.comb += [writer.address.eq(self.dma_address), writer.count.eq(n << 2),
                     self.busy.eq(writer.busy | (pending != 0))]
        m.d.sync += [self.done.eq(0), self.error.eq(0), self.overrun.eq(0)]
        with m.FSM():
            with m.State("IDLE"):
                with m.If(self.dma_start):
                    m.d.comb += [writer.start.eq(1), starting.eq(1)]
                    m.d.sync += [pending.eq(n), overrun.eq(0)]
                    with m.If(n != 0):
                        m.next = "SEND"
                    with m.Else():
                        m.next = "FINISH"
            with m.State("SEND"):
                m.d.comb += [writer.data.valid.eq(1), sent.eq(writer.data.ready)]
                with m.If(sent & (at[:2] == ENTRY_WORDS - 1)):
                    m.d.sync += pending.eq(pending - 1)
                    with m.If(pending == 1):
                        m.next = "FINISH"
            with m.State("FINISH"):
                with m.If(writer.done):
                    m.d.sync += [self.done.eq(1), self.error.eq(writer.error | overrun),
                                 self.overrun.eq(overrun)]
                    m.next = "IDLE"

        # an entry accepted into a slot the DMA still has to read: with a DMA under way, a
        # slot of the entries not yet handed to the writer; with one starting in the same
        # cycle, the oldest slot of a whole-buffer snapshot (the snapshot is taken before the
        # push). Words 1-3 of an entry go to the slot its word 0 went to, and a DMA started
        # after the push reads that slot last, after they are written.
        with m.If(accept):
            with m.If((pending != 0) & (((w_ptr - rd_ptr) & (DEPTH - 1)) < pending)):
                m.d.sync += overrun.eq(1)
            with m.If(starting & (n == DEPTH)):
                m.d.sync += overrun.eq(1)
        return m
