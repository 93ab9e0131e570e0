"""Bit-level SPI slave core for device models: pin-edge driven, with data-sheet timing checks.

A device model (``adis16500.Adis16500Model``, ``bmp390.Bmp390Model``) subclasses
:class:`SpiSlave` and supplies the word-level behaviour (:meth:`SpiSlave.begin`,
:meth:`SpiSlave.word`, :meth:`SpiSlave.end`). The core sees the bus only as pin changes: the
testbench calls :meth:`SpiSlave.pins` whenever CS_N, SCLK or MOSI changes (with the time of the
change in seconds) and drives MISO with the value it returns. Python therefore runs once per
pin edge, never once per clock cycle.

SPI mode 3 (CPOL=1, CPHA=1), MSB first: SCLK idles high, the slave shifts MISO out on the
falling edge and samples MOSI on the rising edge. The checks (each a :class:`SpiTiming`
field; a zero disables it) are the ones SPI data sheets specify: SCLK frequency (edge to edge of
the same polarity), SCLK high and low times, chip-select setup (CS_N falling to the first SCLK
edge) and hold (last SCLK rising edge to CS_N rising), chip-select high time between
transfers, MOSI setup and hold around the sampling edge, SCLK idle level at CS_N edges (CPOL),
and transfers that end inside a word. Violations are recorded (:attr:`SpiSlave.violations`),
never raised, so that a testbench can assert on them.
"""

from __future__ import annotations

from dataclasses import dataclass

_EPS = 1e-12  # seconds: tolerance for times computed from cycle counts


@dataclass(frozen=True)
class SpiTiming:
    """Timing limits of an SPI slave (seconds, Hz). Zero disables a check."""

    f_sclk_max: float
    t_sclk_high_min: float = 0.0
    t_sclk_low_min: float = 0.0
    t_cs_setup_min: float = 0.0  #: CS_N falling edge to first SCLK edge
    t_cs_hold_min: float = 0.0  #: last SCLK rising edge to CS_N rising edge
    t_cs_high_min: float = 0.0  #: CS_N high time between transfers
    t_mosi_setup_min: float = 0.0  #: MOSI stable before the SCLK rising edge
    t_mosi_hold_min: float = 0.0  #: MOSI stable after the SCLK rising edge


@dataclass(frozen=True)
class Violation:
    time: float  #: seconds
    code: str  #: short name: f_sclk, t_high, t_low, t_cs_setup, t_cs_hold, t_cs_high, ...
    message: str


class SpiSlave:
    """Mode-3 SPI slave shift logic and timing checker (see the module docstring)."""

    WORD_BITS = 8
    timing: SpiTiming

    def __init__(self, timing: SpiTiming | None = None):
        if timing is not None:
            self.timing = timing
        self.violations: list[Violation] = []
        self.transfers = 0  #: completed CS_N low periods
        self._cs = 1
        self._sclk = 1
        self._mosi = 0
        self._t_cs_fall = None
        self._t_cs_rise = None
        self._t_fall = None
        self._t_rise = None
        self._t_mosi = -1.0
        self._edge_seen = False
        self._nbits = 0
        self._in = 0
        self._out = 0
        self._miso = 1
        self._stuck = None  # None, 0 or 1: MISO forced for the current transfer

    # ---- hooks for the device ----------------------------------------------------------
    def begin(self) -> None:
        """CS_N fell: a transfer starts."""

    def word(self, index: int, value: int) -> None:
        """Word ``index`` (0-based within the transfer) was received from the master."""

    def next_word(self, index: int) -> int:
        """The word the slave shifts out as word ``index`` of the transfer."""
        return 0

    def end(self, bits: int) -> None:
        """CS_N rose after ``bits`` clock cycles."""

    # ---- pin interface -----------------------------------------------------------------
    def violate(self, t: float, code: str, message: str) -> None:
        self.violations.append(Violation(t, code, message))

    def pins(self, t: float, cs_n: int, sclk: int, mosi: int) -> int:
        """Apply the pin levels at time ``t`` (s); returns the MISO level to drive."""
        tm = self.timing
        cs_n, sclk, mosi = int(cs_n) & 1, int(sclk) & 1, int(mosi) & 1
        if cs_n != self._cs:
            if cs_n == 0:
                self._cs_fall(t, sclk)
            else:
                self._cs_rise(t, sclk)
        elif cs_n == 0:
            if mosi != self._mosi:
                if (tm.t_mosi_hold_min and self._t_rise is not None
                        and self._t_rise >= (self._t_cs_fall or 0)
                        and t - self._t_rise < tm.t_mosi_hold_min - _EPS):
                    self.violate(t, "t_mosi_hold", f"MOSI changed {_ns(t - self._t_rise)} after "
                                 f"SCLK rose (min {_ns(tm.t_mosi_hold_min)})")
                self._t_mosi = t
            if sclk != self._sclk:
                if sclk == 0:
                    self._falling(t)
                else:
                    self._rising(t, mosi)
        if mosi != self._mosi:
            self._t_mosi = t
        self._cs, self._sclk, self._mosi = cs_n, sclk, mosi
        return self.miso

    @property
    def miso(self) -> int:
        if self._cs:
            return 1  # released (high impedance, pulled up)
        if self._stuck is not None:
            return self._stuck
        return self._miso

    def _cs_fall(self, t, sclk):
        tm = self.timing
        if sclk == 0:
            self.violate(t, "cpol", "CS_N fell with SCLK low (mode 3 needs SCLK idle high)")
        if (tm.t_cs_high_min and self._t_cs_rise is not None
                and t - self._t_cs_rise < tm.t_cs_high_min - _EPS):
            self.violate(t, "t_cs_high", f"CS_N high for {_ns(t - self._t_cs_rise)} "
                         f"(min {_ns(tm.t_cs_high_min)})")
        self._t_cs_fall = t
        self._edge_seen = False
        self._nbits = 0
        self._in = 0
        self._stuck = None
        self._cs = 0
        self.begin()
        self._out = self.next_word(0) & ((1 << self.WORD_BITS) - 1)
        self._miso = (self._out >> (self.WORD_BITS - 1)) & 1

    def _cs_rise(self, t, sclk):
        tm = self.timing
        if sclk == 0:
            self.violate(t, "cpol", "CS_N rose with SCLK low (transfer ended mid-cycle)")
        if (tm.t_cs_hold_min and self._t_rise is not None and self._edge_seen
                and t - self._t_rise < tm.t_cs_hold_min - _EPS):
            self.violate(t, "t_cs_hold", f"CS_N rose {_ns(t - self._t_rise)} after the last "
                         f"SCLK rising edge (min {_ns(tm.t_cs_hold_min)})")
        if self._nbits % self.WORD_BITS:
            self.violate(t, "partial_word", f"transfer ended after {self._nbits} bits, "
                         f"not a multiple of {self.WORD_BITS}")
        self._t_cs_rise = t
        self.transfers += 1
        self._cs = 1
        self.end(self._nbits)

    def _first_edge(self, t):
        tm = self.timing
        if not self._edge_seen:
            self._edge_seen = True
            if tm.t_cs_setup_min and t - self._t_cs_fall < tm.t_cs_setup_min - _EPS:
                self.violate(t, "t_cs_setup", f"first SCLK edge {_ns(t - self._t_cs_fall)} "
                             f"after CS_N fell (min {_ns(tm.t_cs_setup_min)})")
            return True
        return False

    def _falling(self, t):
        tm = self.timing
        first = self._first_edge(t)
        if not first and tm.f_sclk_max and self._t_fall is not None \
                and self._t_fall > self._t_cs_fall \
                and t - self._t_fall < 1.0 / tm.f_sclk_max - _EPS:
            self.violate(t, "f_sclk", f"SCLK period {_ns(t - self._t_fall)} "
                         f"(max {tm.f_sclk_max / 1e6:g} MHz)")
        if tm.t_sclk_high_min and self._t_rise is not None and not first \
                and t - self._t_rise < tm.t_sclk_high_min - _EPS:
            self.violate(t, "t_high", f"SCLK high for {_ns(t - self._t_rise)} "
                         f"(min {_ns(tm.t_sclk_high_min)})")
        self._t_fall = t
        bit = self._nbits % self.WORD_BITS
        if bit == 0 and self._nbits:
            self._out = self.next_word(self._nbits // self.WORD_BITS) \
                & ((1 << self.WORD_BITS) - 1)
        self._miso = (self._out >> (self.WORD_BITS - 1 - bit)) & 1

    def _rising(self, t, mosi):
        tm = self.timing
        if self._first_edge(t):
            self.violate(t, "cpha", "SCLK rose before any falling edge (not mode 3)")
        if tm.t_sclk_low_min and self._t_fall is not None \
                and t - self._t_fall < tm.t_sclk_low_min - _EPS:
            self.violate(t, "t_low", f"SCLK low for {_ns(t - self._t_fall)} "
                         f"(min {_ns(tm.t_sclk_low_min)})")
        if tm.f_sclk_max and self._t_rise is not None and self._t_rise > self._t_cs_fall \
                and t - self._t_rise < 1.0 / tm.f_sclk_max - _EPS:
            self.violate(t, "f_sclk", f"SCLK period {_ns(t - self._t_rise)} "
                         f"(max {tm.f_sclk_max / 1e6:g} MHz)")
        if tm.t_mosi_setup_min and t - self._t_mosi < tm.t_mosi_setup_min - _EPS:
            self.violate(t, "t_mosi_setup", f"MOSI changed {_ns(t - self._t_mosi)} before "
                         f"SCLK rose (min {_ns(tm.t_mosi_setup_min)})")
        self._t_rise = t
        self._in = ((self._in << 1) | mosi) & ((1 << self.WORD_BITS) - 1)
        self._nbits += 1
        if self._nbits % self.WORD_BITS == 0:
            self.word(self._nbits // self.WORD_BITS - 1, self._in)
            self._in = 0


def _ns(seconds: float) -> str:
    return f"{seconds * 1e9:.1f} ns"


def drive_transfer(slave: SpiSlave, words, word_bits: int, *, t0: float, half: float,
                   cs_setup: float, cs_hold: float, mosi_lead: float | None = None,
                   cpol: int = 1, bits: int | None = None, low: float | None = None):
    """A software SPI master (mode 3 unless ``cpol=0``) for testing device models: one transfer
    of ``words`` with the given times (seconds). ``mosi_lead`` is how long before the rising
    edge MOSI changes (default: at the falling edge, ``half`` before), ``low`` overrides the
    SCLK low time, ``bits`` truncates the transfer. Returns (received words, end time)."""
    low = half if low is None else low
    lead = low if mosi_lead is None else mosi_lead
    t = t0
    mosi = 0
    idle = cpol
    slave.pins(t, 1, idle, mosi)
    t += 1e-9
    slave.pins(t, 0, idle, mosi)
    t += cs_setup
    total = len(words) * word_bits if bits is None else bits
    rx = []
    cur = 0
    sclk = idle
    for i in range(total):
        w = int(words[i // word_bits])
        b = (w >> (word_bits - 1 - i % word_bits)) & 1
        # falling edge, MOSI change ``lead`` before the rising edge
        sclk = 0
        if lead >= low:
            slave.pins(t, 0, sclk, b)
            miso = slave.pins(t + low, 0, 1, b)
        else:
            slave.pins(t, 0, sclk, mosi)
            slave.pins(t + low - lead, 0, sclk, b)
            miso = slave.pins(t + low, 0, 1, b)
        mosi = b
        sclk = 1
        t += low
        cur = (cur << 1) | miso
        if i % word_bits == word_bits - 1:
            rx.append(cur)
            cur = 0
        t += half
    slave.pins(t - half + cs_hold, 1, sclk, mosi)
    return rx, t - half + cs_hold
