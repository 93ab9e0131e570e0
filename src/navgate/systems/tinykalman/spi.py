"""Seed 001 TinyKalman gateware: the MPU-6500 SPI master (``mpu6500_spi`` block).

Reference: seed 001 ("Sensor Interface: SPI Master for MPU-6500", pinout); the part's SPI
facts and limits from :mod:`navgate.devices.mpu6500` (PS-MPU-6500A-01 sections 3.5, 6.1).

One ``start`` pulse runs two transactions, then offers one result on the stream ``o``:

1. WHO_AM_I: CS_N low, MOSI ``0xF5`` (read 0x75) and one dummy byte: 16 SCLK cycles;
2. burst: CS_N low, MOSI ``0xBB`` (read 0x3B = ACCEL_XOUT_H) and 14 dummy bytes: 120 cycles.

``o.payload``: ``who_am_i`` (the byte read) and the words ``ax, ay, az, gx, gy`` (big-endian
int16 of the burst; temperature and gz are clocked in and dropped: the chip does not use them).

SPI mode 3 (SCLK idles high): the master drives MOSI at SCLK falling edges and the part
changes MISO at falling edges; MISO goes through a two-flip-flop synchroniser (it is an
asynchronous chip input) and is sampled at the end of each SCLK-high half period, i.e. two
system clocks before the next falling edge. That is inside the window in which the part holds
the bit (from t_VD.SDO <= 100 ns after one falling edge to t_HD.SDO after the next) when
``spi_div >= 2``. Every phase lasts ``spi_div`` system clocks (an SCLK half period):
CS_N setup (CS_N fall to the first SCLK fall), each SCLK low and high half, CS_N hold (last
SCLK rise to CS_N rise: high half + hold = 2 ``spi_div``), and the CS_N-high gap. With the
default ``spi_div = 5`` at 10 MHz: SCLK = 1 MHz (the part's limit for all registers), 500 ns
halves (>= 400 ns), setup 500 ns (>= 8 ns), hold 1000 ns (>= 500 ns).

Cycles from ``start`` to ``o.valid``: ``LATENCY = 1 + (3 + 2*16) * spi_div + (3 + 2*120) *
spi_div`` = 1 + 278 ``spi_div`` (1391 at the default: 139.1 us). ``THROUGHPUT`` = 1/LATENCY.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth import Cat, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, enum, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.devices.mpu6500 import BURST_LEN, REG, SPI_READ, WHO_AM_I_VALUE
from navgate.gateware.parameters import CheckedParameters

__all__ = ["Mpu6500Spi", "SPI_WORDS", "DIRECT_KEEP", "DIRECT_PAYLOAD", "spi_cycles"]

#: (word, index of the burst bit that completes it) for the words the chip keeps; bit 0 is the
#: first bit of the address byte
SPI_WORDS = (("ax", 23), ("ay", 39), ("az", 55), ("gx", 87), ("gy", 103))
WHO_BITS = 16
BURST_BITS = 8 * (1 + BURST_LEN)  # 120


def spi_cycles(spi_div: int) -> int:
    """System clocks from ``start`` to the result (see the module docstring)."""
    Mpu6500Spi.check_parameters(spi_div, False, ())  # spi_div 0 once gave 1 clock
    return 1 + ((3 + 2 * WHO_BITS) + (3 + 2 * BURST_BITS)) * spi_div


class _State(enum.Enum, shape=3):
    IDLE = 0
    SETUP = 1
    LOW = 2
    HIGH = 3
    HOLD = 4
    GAP = 5


PAYLOAD = data.StructLayout({
    "who_am_i": unsigned(8),
    "ax": signed(16), "ay": signed(16), "az": signed(16), "gx": signed(16), "gy": signed(16),
})
#: ``direct=True``: ``who_ok`` (WHO_AM_I was 0x70) instead of the byte, and the words with
#: their unused low bits zero (:data:`DIRECT_KEEP`)
DIRECT_PAYLOAD = data.StructLayout({
    "who_ok": unsigned(1),
    "ax": signed(16), "ay": signed(16), "az": signed(16), "gx": signed(16), "gy": signed(16),
})
#: lowest bit of each word the chip uses: the accelerometer words enter as ``>>> 1`` (ax also
#: ``>>> 2``, ``>>> 4``), the rates as ``>>> 6``
DIRECT_KEEP = {"ax": 1, "ay": 1, "az": 1, "gx": 6, "gy": 6}


class Mpu6500Spi(CheckedParameters, wiring.Component):
    """MPU-6500 SPI master: WHO_AM_I read and 14-byte burst per ``start``."""

    @classmethod
    def check_parameters(cls, spi_div, direct, external):
        if not isinstance(spi_div, int) or not 2 <= spi_div <= 1 << 16:
            raise ValueError(f"Mpu6500Spi: spi_div must be an integer >= 2 (clocks per SCLK half "
                             f"period), got {spi_div!r}")
        if external and not direct:
            raise ValueError("Mpu6500Spi: external words need direct=True")
        for name in external:
            if name not in DIRECT_KEEP:
                raise ValueError(f"Mpu6500Spi: unknown word {name!r} in external")

    def __init__(self, spi_div: int = 5, direct: bool = False, external: tuple = ()):
        self.spi_div = spi_div
        #: ``direct``: MISO bits are shifted straight into the registers that keep them (only
        #: the bits the chip uses, :data:`DIRECT_KEEP`; no 16-bit assembly register) and
        #: WHO_AM_I is compared bit by bit as it arrives (one flag, not the byte). The words
        #: change while the next burst comes in. The serial chip's SPI master.
        self.direct = direct
        #: ``external`` (``direct`` only): words whose registers live in the consumer: the
        #: master drives ``bit`` (the sampled MISO bit) and ``shift_<word>`` (one clock per kept
        #: bit, MSB first) with ``last_<word>`` on the last one, and leaves the word 0 in
        #: ``o.payload``. The serial chip shifts ay and az straight into its CORDIC's y and x
        #: registers and the rates into z.
        self.external = tuple(external)
        self.LATENCY = spi_cycles(spi_div)
        self.THROUGHPUT = Fraction(1, self.LATENCY)
        ports = {f"{kind}_{name}": Out(1) for name in self.external
                 for kind in ("shift", "last")}
        if self.external:
            ports["bit"] = Out(1)
        super().__init__({
            **ports,
            "start": In(1),
            "busy": Out(1),
            "miso": In(1),
            "mosi": Out(1),
            "sclk": Out(1, init=1),
            "cs_n": Out(1, init=1),
            "o": Out(stream.Signature(DIRECT_PAYLOAD if direct else PAYLOAD)),
        })

    def elaborate(self, platform):
        m = Module()
        div = self.spi_div
        state = Signal(_State)
        # direct: the counters are set when a transaction starts and the synchroniser refills
        # in two clocks, so they need no reset (the serial chip's list of registers)
        rl = self.direct
        cnt = Signal(range(div), reset_less=rl)
        nbit = Signal(range(BURST_BITS), reset_less=rl)
        burst = Signal(reset_less=rl)  # 0: WHO_AM_I transaction, 1: burst
        shift = Signal(16)
        sync1 = Signal(reset_less=rl)
        sync2 = Signal(reset_less=rl)
        out = Signal(DIRECT_PAYLOAD if self.direct else PAYLOAD)
        if self.direct:
            # written during each transaction before the result is offered: no reset
            regs = {name: Signal(16 - lo, name=f"{name}_bits", reset_less=True)
                    for name, lo in DIRECT_KEEP.items() if name not in self.external}
            who_ok = Signal(reset_less=True)
            m.d.comb += out.who_ok.eq(who_ok)
            for name, lo in DIRECT_KEEP.items():
                if name in regs:
                    m.d.comb += getattr(out, name).eq(Cat(Const(0, lo), regs[name]))
            if self.external:
                m.d.comb += self.bit.eq(sync2)
        out_valid = Signal()

        m.d.sync += [sync1.eq(self.miso), sync2.eq(sync1)]
        m.d.comb += [
            self.busy.eq((state != _State.IDLE) | out_valid),
            self.o.valid.eq(out_valid),
            self.o.payload.eq(out),
        ]
        if self.direct:
            with m.If(self.start & ~out_valid & (state == _State.IDLE)):
                m.d.sync += who_ok.eq(1)
        with m.If(self.o.ready):
            m.d.sync += out_valid.eq(0)

        who_addr = Const(SPI_READ | REG["WHO_AM_I"], 8)
        burst_addr = Const(SPI_READ | REG["ACCEL_XOUT_H"], 8)
        addr = Mux(burst, burst_addr, who_addr)
        # MOSI for bit ``nbit``: the address byte MSB first, then zeros
        addr_bits = Cat(*(addr[7 - k] for k in range(8)))
        mosi_next = Signal()
        m.d.comb += mosi_next.eq(Mux(nbit < 8, addr_bits.bit_select(nbit[:3], 1), 0))

        phase_end = cnt == div - 1
        with m.If(state != _State.IDLE):
            m.d.sync += cnt.eq(Mux(phase_end, 0, cnt + 1))
        last_bit = Mux(burst, nbit == BURST_BITS - 1, nbit == WHO_BITS - 1)
        shifted = Cat(sync2, shift[:15])

        with m.Switch(state):
            with m.Case(_State.IDLE):
                with m.If(self.start & ~out_valid):
                    m.d.sync += [state.eq(_State.SETUP), self.cs_n.eq(0), burst.eq(0),
                                 nbit.eq(0), cnt.eq(0)]
            with m.Case(_State.SETUP):
                with m.If(phase_end):
                    m.d.sync += [state.eq(_State.LOW), self.sclk.eq(0), self.mosi.eq(mosi_next)]
            with m.Case(_State.LOW):
                with m.If(phase_end):
                    m.d.sync += [state.eq(_State.HIGH), self.sclk.eq(1)]
            with m.Case(_State.HIGH):
                with m.If(phase_end):
                    if self.direct:
                        self._direct_bit(m, nbit, burst, sync2, regs, who_ok)
                    else:
                        m.d.sync += shift.eq(shifted)
                        with m.If(burst):
                            for name, bit in SPI_WORDS:
                                with m.If(nbit == bit):
                                    m.d.sync += getattr(out, name).eq(shifted)
                        with m.Elif(nbit == WHO_BITS - 1):
                            m.d.sync += out.who_am_i.eq(shifted[:8])
                    with m.If(last_bit):
                        m.d.sync += [state.eq(_State.HOLD), self.mosi.eq(0)]
                    with m.Else():
                        # next bit: the MOSI mux reads nbit + 1
                        m.d.sync += [state.eq(_State.LOW), self.sclk.eq(0), nbit.eq(nbit + 1)]
                        m.d.sync += self.mosi.eq(Mux(nbit + 1 < 8,
                                                     addr_bits.bit_select((nbit + 1)[:3], 1), 0))
            with m.Case(_State.HOLD):
                with m.If(phase_end):
                    m.d.sync += [state.eq(_State.GAP), self.cs_n.eq(1)]
            with m.Case(_State.GAP):
                with m.If(phase_end):
                    with m.If(burst):
                        m.d.sync += [state.eq(_State.IDLE), out_valid.eq(1)]
                    with m.Else():
                        m.d.sync += [state.eq(_State.SETUP), self.cs_n.eq(0), burst.eq(1),
                                     nbit.eq(0)]
        return m

    def _direct_bit(self, m, nbit, burst, bit, regs, who_ok):
        """``direct``: the MISO bit of burst bit ``nbit`` into the register that keeps it
        (MSB first; a word register shifts during its kept bits only), or, in the WHO_AM_I
        transaction, compared with the expected bit of 0x70."""
        with m.If(burst):
            for name, last in SPI_WORDS:
                with m.If((nbit >= last - 15) & (nbit <= last - DIRECT_KEEP[name])):
                    if name in regs:
                        m.d.sync += regs[name].eq(Cat(bit, regs[name][:-1]))
                    else:
                        m.d.comb += getattr(self, f"shift_{name}").eq(1)
                        with m.If(nbit == last - DIRECT_KEEP[name]):
                            m.d.comb += getattr(self, f"last_{name}").eq(1)
        with m.Elif(nbit >= 8):
            want = Const(WHO_AM_I_VALUE, 8).bit_select(~nbit[:3], 1)
            with m.If(bit != want):
                m.d.sync += who_ok.eq(0)
