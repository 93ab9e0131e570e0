"""SPI mode-3 master PHY shared by ``spi_master_imu`` and ``spi_master_baro`` (seed 000
"spi_phy"): one ``width``-bit transfer per ``start``, MSB first, CPOL=1/CPHA=1.

SCLK idles high. A transfer drives SCLK low and the MSB on MOSI, holds each half period for
``half`` cycles, raises SCLK (the slave samples MOSI on this edge) and lowers it again with the
next bit (the slave shifts MISO out on the falling edge). MISO arrives through a two-flip-flop
synchroniser (asynchronous to ``sync``: the slave's output timing is its own), so the PHY
samples the synchronised MISO :data:`SYNC_STAGES` cycles after the rising edge, i.e. the pin
as it was at that edge. That needs ``half >= SYNC_STAGES + 1`` cycles; the PHY clamps ``half``
to that minimum. After the last bit SCLK stays high for one more half period before ``done``,
which is the chip-select hold time the controllers get for free; a ``start`` in the ``done``
cycle begins the next word at once (back-to-back words of a burst).
"""

from __future__ import annotations

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.wiring import In, Out

SYNC_STAGES = 2
MIN_HALF = SYNC_STAGES + 1


def ready_edge(m: Module, pin, *enables, name: str = "ready"):
    """A one-cycle pulse at each rising edge of a device's data-ready line (ADIS16500 DR,
    BMP390 INT), asynchronous to ``sync``: the pin passes a two-flip-flop synchroniser and the
    edge is taken of the level gated by ``enables`` (the mode bits), so that switching the
    mode on while the line is already high also gives an edge."""
    level = Signal(name=f"{name}_s")
    armed = Signal(name=f"{name}_armed")
    armed_d = Signal(name=f"{name}_armed_d")
    m.submodules[f"{name}_sync"] = FFSynchronizer(pin, level, init=0, stages=SYNC_STAGES)
    gate = level
    for e in enables:
        gate = gate & e
    m.d.comb += armed.eq(gate)
    m.d.sync += armed_d.eq(armed)
    return armed & ~armed_d


def sample_timer(m: Module, tick_cycles: int, rate) -> Signal:
    """The sensor masters' sample timer (seed 000 ``UPDATE_RATE``, ``BARO_RATE``): a prescaler
    of ``tick_cycles`` clock cycles makes ticks, and every ``rate``-th tick (``rate``, a 16-bit
    register, read at each tick; 0 and 1 both mean every tick) gives a one-cycle strobe, which
    is returned. The caller decides what the strobe starts."""
    pre = Signal(range(tick_cycles), name="timer_pre")
    ticks = Signal(16, name="timer_ticks")
    tick = Signal(name="timer_tick")
    due = Signal(name="timer_due")
    m.d.comb += [tick.eq(pre == tick_cycles - 1), due.eq(tick & (ticks + 1 >= rate))]
    m.d.sync += pre.eq(0 if tick_cycles == 1 else pre + 1)
    with m.If(tick):
        m.d.sync += [pre.eq(0), ticks.eq(Mux(due, 0, ticks + 1))]
    return due


def slave_pins(m: Module, sclk_pin, mosi_pin, cs_n_pin):
    """An SPI slave's view of the master's pins (asynchronous to ``sync``): each pin through a
    two-flip-flop synchroniser, edges detected on the synchronised levels (every pin event is
    seen ``SYNC_STAGES + 1`` cycles late, all three alike). Returns (mosi, sclk_rise,
    cs_fall, cs_rise)."""
    sclk, mosi, cs_n = Signal(init=1), Signal(), Signal(init=1)
    m.submodules.sclk_sync = FFSynchronizer(sclk_pin, sclk, init=1, stages=SYNC_STAGES)
    m.submodules.mosi_sync = FFSynchronizer(mosi_pin, mosi, init=0, stages=SYNC_STAGES)
    m.submodules.cs_sync = FFSynchronizer(cs_n_pin, cs_n, init=1, stages=SYNC_STAGES)
    sclk_d, cs_d = Signal(init=1), Signal(init=1)
    m.d.sync += [sclk_d.eq(sclk), cs_d.eq(cs_n)]
    cs_fall, cs_rise, sclk_rise = Signal(), Signal(), Signal()
    m.d.comb += [cs_fall.eq(cs_d & ~cs_n), cs_rise.eq(~cs_d & cs_n),
                 sclk_rise.eq(~sclk_d & sclk)]
    return mosi, sclk_rise, cs_fall, cs_rise


class SpiPhy(wiring.Component):
    """Mode-3 SPI shift engine (no chip select): ``start`` -> ``done`` pulse with ``rx``."""

    def __init__(self, width: int):
        self.width = width
        super().__init__({
            "start": In(1), "tx": In(width), "half": In(8),
            "busy": Out(1), "done": Out(1), "rx": Out(width),
            "sclk": Out(1, init=1), "mosi": Out(1), "miso": In(1),
        })

    def elaborate(self, platform):
        m = Module()
        w = self.width
        half = Signal(8)
        m.d.comb += half.eq(Mux(self.half < MIN_HALF, MIN_HALF, self.half))
        cnt = Signal(8)
        bit = Signal(range(w))
        sh = Signal(w)
        with m.FSM(name="phy"):
            with m.State("IDLE"):
                with m.If(self.start):
                    m.d.sync += [sh.eq(self.tx << 1), self.mosi.eq(self.tx[-1]),
                                 self.sclk.eq(0), cnt.eq(1), bit.eq(0)]
                    m.next = "LOW"
            with m.State("LOW"):
                m.d.comb += self.busy.eq(1)
                m.d.sync += cnt.eq(cnt + 1)
                with m.If(cnt >= half):
                    m.d.sync += [self.sclk.eq(1), cnt.eq(1)]
                    m.next = "HIGH"
            with m.State("HIGH"):
                m.d.comb += self.busy.eq(1)
                m.d.sync += cnt.eq(cnt + 1)
                with m.If(cnt == SYNC_STAGES):
                    m.d.sync += self.rx.eq(Cat(self.miso, self.rx[:-1]))
                with m.If(cnt >= half):
                    m.d.sync += cnt.eq(1)
                    with m.If(bit == w - 1):
                        m.next = "TAIL"
                    with m.Else():
                        m.d.sync += [self.sclk.eq(0), self.mosi.eq(sh[-1]), sh.eq(sh << 1),
                                     bit.eq(bit + 1)]
                        m.next = "LOW"
            with m.State("TAIL"):
                m.d.comb += self.busy.eq(1)
                m.d.sync += cnt.eq(cnt + 1)
                with m.If(cnt >= half):
                    m.d.comb += self.done.eq(1)
                    with m.If(self.start):  # back-to-back word: start it now
                        m.d.sync += [sh.eq(self.tx << 1), self.mosi.eq(self.tx[-1]),
                                     self.sclk.eq(0), cnt.eq(1), bit.eq(0)]
                        m.next = "LOW"
                    with m.Else():
                        m.d.sync += self.mosi.eq(0)
                        m.next = "IDLE"
        return m
