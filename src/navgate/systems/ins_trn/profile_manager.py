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

DMA: a start pulse (PROF_CTRL.start) snapshots the newest ``min(PROF_COUNT, fill)`` entries
and writes them oldest first, contiguously from PROF_ADDR (16-byte aligned), over an AXI4
write master in legal Zynq HP-port bursts (:class:`navgate.gateware.axi4.AxiBurstWriter`).
The FIFO is not consumed: the PS reads the current window whenever it correlates. Entries keep
arriving during a DMA; if one lands in a slot the DMA has not read yet (possible only when the
snapshot is the whole buffer and a push arrives within the first microseconds), the
``overrun`` flag is raised with ``done`` so the PS can discard the transfer. ``done`` pulses at
the end (for the update interrupt), with ``error`` on a bus error or overrun.
"""

from __future__ import annotations

from amaranth import Module, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware.axi4 import AxiBurstWriter, axi4_write_signature

DEPTH = 64

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
    """Profile FIFO (64 x 128 bit, block RAM) with an AXI4 burst DMA to memory."""

    LATENCY = 1  #: an accepted entry is counted in ``fill`` one cycle later
    THROUGHPUT = 1

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
        m.submodules.memory = memory = Memory(shape=128, depth=DEPTH, init=[])
        write = memory.write_port()
        read = memory.read_port()
        m.submodules.writer = writer = AxiBurstWriter(count_width=9)
        wiring.connect(m, wiring.flipped(self.axi), writer.axi)

        w_ptr = Signal(6)
        fill = Signal(7)
        m.d.comb += [self.entry.ready.eq(1), self.fill.eq(fill)]
        pushing = self.entry.valid
        m.d.comb += [write.addr.eq(w_ptr), write.data.eq(self.entry.payload.as_value()),
                     write.en.eq(pushing)]
        with m.If(pushing):
            m.d.sync += w_ptr.eq(w_ptr + 1)
            with m.If(fill < DEPTH):
                m.d.sync += fill.eq(fill + 1)

        # ---------------------------------------------------------------- DMA
        rd_ptr = Signal(6)
        pending = Signal(7)  # entries of the snapshot not yet fully handed to the writer
        word = Signal(2)
        current = Signal(128)
        overrun = Signal()
        m.d.comb += [read.addr.eq(rd_ptr), writer.data.payload.eq(current.word_select(word, 32))]
        # a push into a slot the DMA still has to read
        with m.If(pushing & (pending != 0) & (((w_ptr - rd_ptr) & (DEPTH - 1)) < pending)):
            m.d.sync += overrun.eq(1)
        n = Signal(7)
        m.d.comb += n.eq(self.dma_count)
        with m.If(fill < self.dma_count):
            m.d.comb += n.eq(fill)
        m.d.comb += [writer.address.eq(self.dma_address), writer.count.eq(n << 2),
                     self.busy.eq(writer.busy | (pending != 0))]
        m.d.sync += [self.done.eq(0), self.error.eq(0), self.overrun.eq(0)]
        with m.FSM():
            with m.State("IDLE"):
                with m.If(self.dma_start):
                    m.d.comb += writer.start.eq(1)
                    m.d.sync += [rd_ptr.eq(w_ptr - n), pending.eq(n), overrun.eq(0)]
                    with m.If(n != 0):
                        m.next = "FETCH"
                    with m.Else():
                        m.next = "FINISH"
            with m.State("FETCH"):  # the read port answers one cycle after the address
                m.next = "LOAD"
            with m.State("LOAD"):
                m.d.sync += [current.eq(read.data), word.eq(0)]
                m.next = "SEND"
            with m.State("SEND"):
                m.d.comb += writer.data.valid.eq(1)
                with m.If(writer.data.ready):
                    m.d.sync += word.eq(word + 1)
                    with m.If(word == 3):
                        m.d.sync += [rd_ptr.eq(rd_ptr + 1), pending.eq(pending - 1)]
                        with m.If(pending == 1):
                            m.next = "FINISH"
                        with m.Else():
                            m.next = "FETCH"
            with m.State("FINISH"):
                with m.If(writer.done):
                    m.d.sync += [self.done.eq(1), self.error.eq(writer.error | overrun),
                                 self.overrun.eq(overrun)]
                    m.next = "IDLE"
        return m
