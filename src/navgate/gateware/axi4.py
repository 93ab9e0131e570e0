"""AXI4 write-channel signature and a burst writer that moves 32-bit words to memory.

AMBA AXI (ARM IHI 0022) write channels AW, W and B, as a Zynq-7000 high-performance (HP) slave
port accepts them: the HP ports are AXI3, so bursts are INCR with at most 16 beats, and no
burst may cross a 4 KB boundary (A3.4.1). :class:`AxiBurstWriter` takes a start address and a
word count, pulls the words from a stream, and issues the fewest legal bursts (at most 16
beats, split at 4 KB boundaries), one outstanding burst at a time; it reports an error if any
B response is not OKAY.
"""

from __future__ import annotations

from amaranth import Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

MAX_BEATS = 16  #: AXI3 (Zynq HP ports): at most 16 beats per INCR burst
BOUNDARY = 4096  #: no burst may cross a 4 KB boundary


def axi4_write_signature(addr_width: int = 32, data_width: int = 32) -> wiring.Signature:
    """AW, W and B of an AXI4 master (flip it for a slave), with a one-bit ID (always 0)."""
    return wiring.Signature({
        "awid": Out(1), "awaddr": Out(addr_width), "awlen": Out(8), "awsize": Out(3),
        "awburst": Out(2),
        "awcache": Out(4), "awprot": Out(3), "awvalid": Out(1), "awready": In(1),
        "wdata": Out(data_width), "wstrb": Out(data_width // 8), "wlast": Out(1),
        "wvalid": Out(1), "wready": In(1),
        "bid": In(1), "bresp": In(2), "bvalid": In(1), "bready": Out(1),
    })


def plan_bursts(address: int, words: int) -> list[tuple[int, int]]:
    """The bursts (address, beats) the writer issues for ``words`` 32-bit words at ``address``."""
    bursts = []
    while words:
        to_boundary = (BOUNDARY - address % BOUNDARY) // 4
        beats = min(words, MAX_BEATS, to_boundary)
        bursts.append((address, beats))
        address += 4 * beats
        words -= beats
    return bursts


class AxiBurstWriter(wiring.Component):
    """Write ``count`` words from ``data`` to ``address`` (word aligned) over AXI4 bursts.

    ``start`` (a pulse while not ``busy``) latches ``address`` and ``count``; ``done`` pulses
    when the last B response has arrived; ``error`` pulses with ``done`` if any response was
    not OKAY. The data stream is pulled only while a W beat can be sent.
    """

    def __init__(self, count_width: int = 12):
        super().__init__({
            "axi": Out(axi4_write_signature()),
            "data": In(stream.Signature(32)),
            "start": In(1), "address": In(32), "count": In(count_width),
            "busy": Out(1), "done": Out(1), "error": Out(1),
        })
        self.count_width = count_width

    def elaborate(self, platform):
        m = Module()
        axi = self.axi
        address = Signal(32)
        remaining = Signal(self.count_width)
        beats = Signal(5)  # beats of the current burst
        beat = Signal(5)
        failed = Signal()
        m.d.comb += [axi.awsize.eq(2), axi.awburst.eq(1), axi.awcache.eq(0b0011),
                     axi.awprot.eq(0), axi.wstrb.eq(0xF), axi.wdata.eq(self.data.payload)]
        m.d.sync += [self.done.eq(0), self.error.eq(0)]
        to_boundary = Signal(11)
        m.d.comb += to_boundary.eq((BOUNDARY - address[:12]) >> 2)
        with m.FSM():
            with m.State("IDLE"):
                with m.If(self.start & (self.count != 0)):
                    m.d.sync += [address.eq(self.address), remaining.eq(self.count),
                                 failed.eq(0)]
                    m.next = "PLAN"
                with m.Elif(self.start):
                    m.d.sync += self.done.eq(1)
            with m.State("PLAN"):
                m.d.comb += self.busy.eq(1)
                # beats = min(remaining, 16, words to the 4 KB boundary)
                capped = Signal(5)
                n = Signal(5)
                m.d.comb += [capped.eq(MAX_BEATS), n.eq(capped)]
                with m.If(remaining < MAX_BEATS):
                    m.d.comb += capped.eq(remaining)
                with m.If(to_boundary < capped):
                    m.d.comb += n.eq(to_boundary)
                m.d.sync += [beats.eq(n), beat.eq(0)]
                m.next = "AW"
            with m.State("AW"):
                m.d.comb += [self.busy.eq(1), axi.awvalid.eq(1), axi.awaddr.eq(address),
                             axi.awlen.eq(beats - 1)]
                with m.If(axi.awready):
                    m.next = "W"
            with m.State("W"):
                m.d.comb += [self.busy.eq(1), axi.wvalid.eq(self.data.valid),
                             axi.wlast.eq(beat == beats - 1),
                             self.data.ready.eq(axi.wready)]
                with m.If(self.data.valid & axi.wready):
                    m.d.sync += beat.eq(beat + 1)
                    with m.If(beat == beats - 1):
                        m.next = "B"
            with m.State("B"):
                m.d.comb += [self.busy.eq(1), axi.bready.eq(1)]
                with m.If(axi.bvalid):
                    next_failed = failed | (axi.bresp != 0)
                    m.d.sync += [address.eq(address + (beats << 2)),
                                 remaining.eq(remaining - beats), failed.eq(next_failed)]
                    with m.If(remaining == beats):
                        m.d.sync += [self.done.eq(1), self.error.eq(next_failed)]
                        m.next = "IDLE"
                    with m.Else():
                        m.next = "PLAN"
        return m
