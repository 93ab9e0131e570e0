"""InvenSense (TDK) MPU-6500 six-axis IMU: registers, words, SPI timing and a bit-level device
model for testbenches.

References: MPU-6500 Register Map and Descriptions (RM-MPU-6500A-00 rev 2.1) for the register
addresses, reset values, full-scale selections and the big-endian data registers; MPU-6500
Product Specification (PS-MPU-6500A-01 rev 1.1): section 3.1/3.2 sensitivities, section 3.5
SPI timing (the MPU-6000/6500 family table: f_SCLK <= 1 MHz for all registers, 20 MHz for
reading the sensor and interrupt registers, t_LOW, t_HIGH >= 400 ns, t_SU.CS >= 8 ns,
t_HD.CS >= 500 ns, t_SU.SDI >= 11 ns, t_HD.SDI >= 7 ns, t_VD.SDO <= 100 ns) and section 6.1
(SPI: MSB first, data latched on the rising edge of SCLK and transitioned on the falling edge,
i.e. SPI mode 0 or 3; a transaction is an address byte, bit 7 = read, then data bytes with
address auto-increment; at least 16 clocks). Seed 001 reads the 14-byte burst at
ACCEL_XOUT_H: ax, ay, az, temperature, gx, gy, gz, each a big-endian int16.

Contents
--------
* Facts: :data:`REG`, :data:`WHO_AM_I_VALUE`, :data:`BURST_LEN`, sensitivities,
  :data:`SPI_TIMING` (:class:`SpiTiming`).
* Words: :func:`encode_accel`, :func:`encode_gyro`, :func:`encode_temp` (physical -> int16,
  round to nearest, saturate), :func:`decode_burst`, :func:`encode_burst`.
* :class:`Mpu6500`: register-level model, one SPI transaction at a time (bytes in, bytes out).
* :class:`Mpu6500Bus`: bit-level device model driven by the pin levels (CS_N, SCLK, MOSI) at
  given times; returns MISO. It serves a stream of samples (one per complete burst read from
  ACCEL_XOUT_H: the burst after the one that returned sample k returns sample k+1; the real
  part updates its registers at its own output data rate, a testbench wants one sample per
  read), checks the master's timing against :data:`SPI_TIMING` (violations are recorded, not
  raised), and injects faults: ``"stuck0"`` / ``"stuck1"`` (MISO stuck at a level, the part
  otherwise working), ``"who_am_i"`` (WHO_AM_I answers ``wrong_who_am_i``, e.g. 0x71 of an
  MPU-9250), ``"absent"`` (no part: MISO is the board's pull level, default high).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

__all__ = [
    "REG", "WHO_AM_I_VALUE", "SPI_READ", "BURST_LEN", "BURST_WORDS", "GYRO_SENSITIVITY",
    "ACCEL_SENSITIVITY", "TEMP_SENSITIVITY", "TEMP_OFFSET_C", "SpiTiming", "SPI_TIMING",
    "FAULTS", "to_word", "encode_accel", "encode_gyro", "encode_temp", "decode_burst",
    "encode_burst", "Mpu6500", "Mpu6500Bus",
]

#: register addresses (RM-MPU-6500A-00)
REG = {
    "SMPLRT_DIV": 0x19,
    "CONFIG": 0x1A,
    "GYRO_CONFIG": 0x1B,
    "ACCEL_CONFIG": 0x1C,
    "ACCEL_CONFIG2": 0x1D,
    "ACCEL_XOUT_H": 0x3B,
    "ACCEL_XOUT_L": 0x3C,
    "ACCEL_YOUT_H": 0x3D,
    "ACCEL_YOUT_L": 0x3E,
    "ACCEL_ZOUT_H": 0x3F,
    "ACCEL_ZOUT_L": 0x40,
    "TEMP_OUT_H": 0x41,
    "TEMP_OUT_L": 0x42,
    "GYRO_XOUT_H": 0x43,
    "GYRO_XOUT_L": 0x44,
    "GYRO_YOUT_H": 0x45,
    "GYRO_YOUT_L": 0x46,
    "GYRO_ZOUT_H": 0x47,
    "GYRO_ZOUT_L": 0x48,
    "USER_CTRL": 0x6A,
    "PWR_MGMT_1": 0x6B,
    "PWR_MGMT_2": 0x6C,
    "WHO_AM_I": 0x75,
}
WHO_AM_I_VALUE = 0x70  #: MPU-6500's WHO_AM_I value
SPI_READ = 0x80  #: bit 7 of the address byte: 1 = read
BURST_LEN = 14  #: ACCEL_XOUT_H .. GYRO_ZOUT_L
BURST_WORDS = ("ax", "ay", "az", "temp", "gx", "gy", "gz")
#: first and last address of the sensor registers readable at up to 20 MHz
SENSOR_REGS = (REG["ACCEL_XOUT_H"], REG["GYRO_ZOUT_L"])

#: LSB per (deg/s) for GYRO_CONFIG.GYRO_FS_SEL = 0..3 (+-250, 500, 1000, 2000 deg/s)
GYRO_SENSITIVITY = (131.0, 65.5, 32.8, 16.4)
#: LSB per g for ACCEL_CONFIG.ACCEL_FS_SEL = 0..3 (+-2, 4, 8, 16 g)
ACCEL_SENSITIVITY = (16384.0, 8192.0, 4096.0, 2048.0)
TEMP_SENSITIVITY = 333.87  #: LSB per degC
TEMP_OFFSET_C = 21.0  #: degC at TEMP_OUT = 0 (room-temperature offset 0)


@dataclass(frozen=True)
class SpiTiming:
    """SPI timing limits in ns (PS-MPU-6500A-01 section 3.5)."""

    sclk_min_period: float = 1000.0  #: f_SCLK <= 1 MHz, all registers
    sclk_min_period_sensor: float = 50.0  #: f_SCLK <= 20 MHz, sensor/interrupt reads
    t_low: float = 400.0  #: SCLK low period, min
    t_high: float = 400.0  #: SCLK high period, min
    t_su_cs: float = 8.0  #: CS_N fall to first SCLK edge, min
    t_hd_cs: float = 500.0  #: last SCLK rising edge to CS_N rise, min
    t_su_sdi: float = 11.0  #: MOSI stable before the SCLK rising edge, min
    t_hd_sdi: float = 7.0  #: MOSI stable after the SCLK rising edge, min
    t_vd_sdo: float = 100.0  #: SCLK falling edge to MISO valid, max


SPI_TIMING = SpiTiming()
FAULTS = (None, "stuck0", "stuck1", "who_am_i", "absent")


# ------------------------------------------------------------------------------- words


def to_word(value: float) -> tuple[int, bool]:
    """Round to the nearest int16, saturating; returns (word, saturated)."""
    if not math.isfinite(value):
        raise ValueError("sensor value must be finite")
    w = int(round(value))
    sat = w > 32767 or w < -32768
    return max(-32768, min(32767, w)), sat


def encode_accel(g: float, fs_sel: int = 0) -> tuple[int, bool]:
    """Acceleration in g -> ACCEL_*OUT word at ACCEL_FS_SEL ``fs_sel``; (word, saturated)."""
    return to_word(float(g) * ACCEL_SENSITIVITY[fs_sel])


def encode_gyro(dps: float, fs_sel: int = 0) -> tuple[int, bool]:
    """Rate in deg/s -> GYRO_*OUT word at GYRO_FS_SEL ``fs_sel``; (word, saturated)."""
    return to_word(float(dps) * GYRO_SENSITIVITY[fs_sel])


def encode_temp(temp_c: float) -> tuple[int, bool]:
    """Temperature in degC -> TEMP_OUT word; (word, saturated)."""
    return to_word((float(temp_c) - TEMP_OFFSET_C) * TEMP_SENSITIVITY)


def decode_burst(burst: bytes) -> dict[str, int]:
    """14 burst bytes -> signed words ax, ay, az, temp, gx, gy, gz (big-endian int16)."""
    if len(burst) != BURST_LEN:
        raise ValueError(f"an MPU-6500 burst is {BURST_LEN} bytes, got {len(burst)}")
    words = [int.from_bytes(burst[i:i + 2], "big", signed=True) for i in range(0, 14, 2)]
    return dict(zip(BURST_WORDS, words, strict=True))


def encode_burst(words: Sequence[int] | dict) -> bytes:
    """Inverse of :func:`decode_burst`: seven int16 words (or a dict by name) -> 14 bytes."""
    if isinstance(words, dict):
        words = [words[k] for k in BURST_WORDS]
    words = [int(w) for w in words]
    if len(words) != 7:
        raise ValueError(f"a burst holds 7 words, got {len(words)}")
    out = bytearray()
    for name, w in zip(BURST_WORDS, words, strict=True):
        if not -32768 <= w <= 32767:
            raise ValueError(f"{name} word {w} does not fit int16")
        out += w.to_bytes(2, "big", signed=True)
    return bytes(out)


# ------------------------------------------------------------------------------- registers


class Mpu6500:
    """Register-level MPU-6500 model on SPI: writes configure, reads return sensor words.

    ``set_sample`` loads physical values (g, deg/s, degC) into the data registers with the
    configured full scale, rounding to the nearest LSB and saturating (counted in
    ``saturated``); ``set_words`` loads words. ``transfer`` is one SPI transaction (CS low ..
    high): the first MOSI byte is the address (bit 7 = read), then the part auto-increments.
    WHO_AM_I is read-only.
    """

    def __init__(self):
        self.regs = bytearray(128)
        self.regs[REG["WHO_AM_I"]] = WHO_AM_I_VALUE
        self.regs[REG["PWR_MGMT_1"]] = 0x01  # reset value: auto clock select
        self.saturated = 0

    @property
    def gyro_fs(self) -> int:
        return (self.regs[REG["GYRO_CONFIG"]] >> 3) & 0x3

    @property
    def accel_fs(self) -> int:
        return (self.regs[REG["ACCEL_CONFIG"]] >> 3) & 0x3

    def _put(self, addr: int, word: int) -> None:
        u = word & 0xFFFF
        self.regs[addr] = u >> 8
        self.regs[addr + 1] = u & 0xFF

    def set_words(self, words: Sequence[int] | dict) -> None:
        """Load the seven burst words (ax, ay, az, temp, gx, gy, gz) into the registers."""
        self.regs[REG["ACCEL_XOUT_H"]:REG["ACCEL_XOUT_H"] + BURST_LEN] = encode_burst(words)

    def set_sample(self, accel_g, gyro_dps, temp_c: float = 25.0) -> None:
        for i, v in enumerate(accel_g):
            w, s = encode_accel(v, self.accel_fs)
            self.saturated += s
            self._put(REG["ACCEL_XOUT_H"] + 2 * i, w)
        for i, v in enumerate(gyro_dps):
            w, s = encode_gyro(v, self.gyro_fs)
            self.saturated += s
            self._put(REG["GYRO_XOUT_H"] + 2 * i, w)
        w, s = encode_temp(temp_c)
        self.saturated += s
        self._put(REG["TEMP_OUT_H"], w)

    def read_reg(self, addr: int) -> int:
        return self.regs[addr & 0x7F]

    def write_reg(self, addr: int, value: int) -> None:
        a = addr & 0x7F
        if a != REG["WHO_AM_I"]:  # read-only
            self.regs[a] = value & 0xFF

    def transfer(self, mosi: bytes) -> bytes:
        """One SPI transaction; returns the MISO bytes (first byte is don't-care 0)."""
        if not mosi:
            raise ValueError("an SPI transaction needs at least the address byte")
        addr = mosi[0] & 0x7F
        read = bool(mosi[0] & SPI_READ)
        out = bytearray([0])
        for k, byte in enumerate(mosi[1:]):
            a = (addr + k) & 0x7F
            if read:
                out.append(self.read_reg(a))
            else:
                self.write_reg(a, byte)
                out.append(0)
        return bytes(out)

    def read_burst(self) -> bytes:
        """The driver's 14-byte burst from ACCEL_XOUT_H."""
        return self.transfer(bytes([SPI_READ | REG["ACCEL_XOUT_H"]]) + bytes(BURST_LEN))[1:]


# ------------------------------------------------------------------------------- pins


@dataclass
class BusStats:
    """What a :class:`Mpu6500Bus` saw."""

    transactions: int = 0
    bursts: int = 0  #: complete 14-byte reads from ACCEL_XOUT_H (samples served)
    who_am_i_reads: int = 0
    writes: int = 0
    underruns: int = 0  #: bursts read after the sample stream ran out (last sample repeated)
    violations: list[str] = field(default_factory=list)


class Mpu6500Bus:
    """Bit-level MPU-6500 on the SPI pins, for testbenches.

    Call :meth:`pins` whenever the master's pins may have changed (every clock cycle, or on
    every edge), with the time in ns; it returns the MISO level. The part follows SPI mode 0
    or 3 (the SCLK level at CS_N fall selects it and must be the same at CS_N rise): MOSI is
    sampled on the SCLK rising edge, MISO changes on the falling edge (mode 3; in mode 0 the
    first bit is also driven at CS_N fall). MISO is driven low outside data bytes of a read
    (the real pin is high-impedance while CS_N is high; testbenches see the pull level then
    only with ``fault="absent"``).

    ``samples``: an iterable of seven-word bursts (sequences or dicts of
    :data:`BURST_WORDS`); one per complete burst read, see the module docstring.
    ``timing``: limits to check (``None``: no checks, for simulations with shortened SPI
    clocks). Violations go to ``stats.violations`` (at most ``max_violations`` kept, all
    counted in ``violation_count``). ``log`` records every transaction with the bytes seen on
    the MISO line (``keep_log``), from which a testbench derives what the master read.
    """

    def __init__(self, samples: Iterable | None = None, *, timing: SpiTiming | None = SPI_TIMING,
                 fault: str | None = None, wrong_who_am_i: int = 0x71, pull: int = 1,
                 max_violations: int = 20, keep_log: bool = True):
        if fault not in FAULTS:
            raise ValueError(f"unknown fault {fault!r}; known: {FAULTS}")
        self.regs = Mpu6500()
        self._samples = iter(samples) if samples is not None else iter(())
        self.timing = timing
        self.fault = fault
        self.wrong_who_am_i = wrong_who_am_i & 0xFF
        self.pull = 1 if pull else 0
        self.max_violations = max_violations
        self.keep_log = keep_log
        #: per transaction: (address, read, bytes on the MISO line as the master sampled
        #: them at the SCLK rising edges, faults included)
        self.log: list[tuple[int | None, bool, bytes]] = []
        self.violation_count = 0
        self.stats = BusStats()
        self._exhausted = False
        self._load_next()
        # pin state
        self._cs_n = 1
        self._sclk = None
        self._mosi = 0
        self._miso = 0
        self._t_mosi = -math.inf
        self._t_cs_fall = -math.inf
        self._t_sclk_fall = -math.inf
        self._t_sclk_rise = -math.inf
        self._reset_transaction()

    # ------------------------------------------------------------ sample stream
    def _load_next(self) -> None:
        try:
            words = next(self._samples)
        except StopIteration:
            self._exhausted = True
            return
        self.regs.set_words(words)

    # ------------------------------------------------------------ bookkeeping
    def _violate(self, t: float, text: str) -> None:
        self.violation_count += 1
        if len(self.stats.violations) < self.max_violations:
            self.stats.violations.append(f"t={t:.0f} ns: {text}")

    def _reset_transaction(self) -> None:
        self._bits = 0  # bits clocked in (rising edges)
        self._shift_in = 0
        self._addr = None
        self._read = False
        self._out_byte = 0
        self._min_low = math.inf
        self._min_high = math.inf
        self._min_period = math.inf
        self._mode_idle = None
        self._line_byte = 0
        self._line_bytes = bytearray()

    def _who(self, addr: int) -> int:
        if addr == REG["WHO_AM_I"] and self.fault == "who_am_i":
            return self.wrong_who_am_i
        return self.regs.read_reg(addr)

    def _next_out_bit(self) -> int:
        """MISO bit for the bit index about to be shifted (after ``self._bits`` rising edges)."""
        if self._addr is None or not self._read or self._bits < 8:
            return 0
        k = self._bits - 8
        byte = self._who((self._addr + k // 8) & 0x7F)
        return (byte >> (7 - k % 8)) & 1

    def set_fault(self, fault: str | None) -> None:
        """Change the injected fault (takes effect immediately)."""
        if fault not in FAULTS:
            raise ValueError(f"unknown fault {fault!r}; known: {FAULTS}")
        self.fault = fault

    def _line(self) -> int:
        if self.fault == "absent":
            return self.pull
        if self.fault == "stuck0":
            return 0
        if self.fault == "stuck1":
            return 1
        return self._miso

    # ------------------------------------------------------------ the pins
    def pins(self, t_ns: float, cs_n: int, sclk: int, mosi: int) -> int:
        """Update with the master's pin levels at time ``t_ns``; returns MISO."""
        cs_n, sclk, mosi = int(bool(cs_n)), int(bool(sclk)), int(bool(mosi))
        tm = self.timing
        if mosi != self._mosi:
            if tm is not None and not cs_n and sclk and self._sclk == 1 \
                    and t_ns - self._t_sclk_rise < tm.t_hd_sdi:
                self._violate(t_ns, "MOSI changed within t_HD.SDI of the SCLK rising edge")
            self._mosi = mosi
            self._t_mosi = t_ns
        if cs_n != self._cs_n:
            if not cs_n:  # CS_N fall: a transaction starts
                self._reset_transaction()
                self._mode_idle = sclk
                self._t_cs_fall = t_ns
                self._miso = self._next_out_bit()
            else:  # CS_N rise: it ends
                self._end_transaction(t_ns, sclk)
            self._cs_n = cs_n
            self._sclk = sclk
            return self._line()
        if self._sclk is None:
            self._sclk = sclk
        if cs_n:
            self._sclk = sclk
            return self._line()
        if sclk != self._sclk:
            if sclk:  # rising edge: sample MOSI
                if tm is not None:
                    if t_ns - self._t_sclk_fall < tm.t_low and self._t_sclk_fall > self._t_cs_fall:
                        self._min_low = min(self._min_low, t_ns - self._t_sclk_fall)
                    if t_ns - self._t_mosi < tm.t_su_sdi:
                        self._violate(t_ns, "MOSI changed within t_SU.SDI of the SCLK "
                                            "rising edge")
                    if self._t_sclk_rise > self._t_cs_fall:
                        self._min_period = min(self._min_period, t_ns - self._t_sclk_rise)
                self._t_sclk_rise = t_ns
                self._line_byte = ((self._line_byte << 1) | self._line()) & 0xFF
                if self._bits % 8 == 7:
                    self._line_bytes.append(self._line_byte)
                self._shift_in = ((self._shift_in << 1) | mosi) & 0xFF
                self._bits += 1
                if self._bits % 8 == 0:
                    self._byte_in(self._shift_in)
            else:  # falling edge: shift MISO
                if tm is not None:
                    if self._bits == 0 and t_ns - self._t_cs_fall < tm.t_su_cs:
                        self._violate(t_ns, "first SCLK edge within t_SU.CS of CS_N fall")
                    if self._t_sclk_rise > self._t_cs_fall:
                        self._min_high = min(self._min_high, t_ns - self._t_sclk_rise)
                self._t_sclk_fall = t_ns
                self._miso = self._next_out_bit()
            self._sclk = sclk
        return self._line()

    def _byte_in(self, byte: int) -> None:
        if self._bits == 8:
            self._addr = byte & 0x7F
            self._read = bool(byte & SPI_READ)
            return
        if not self._read:
            self.regs.write_reg((self._addr + self._bits // 8 - 2) & 0x7F, byte)
            self.stats.writes += 1

    def _end_transaction(self, t_ns: float, sclk: int) -> None:
        tm = self.timing
        nbytes = self._bits // 8
        if tm is not None:
            if self._bits % 8 or self._bits < 16:
                self._violate(t_ns, f"transaction of {self._bits} SCLK cycles (need a multiple "
                                    "of 8, at least 16)")
            if sclk != self._mode_idle:
                self._violate(t_ns, "SCLK idle level differs at CS_N fall and rise (mode)")
            if t_ns - self._t_sclk_rise < tm.t_hd_cs:
                self._violate(t_ns, f"CS_N rose {t_ns - self._t_sclk_rise:.0f} ns after the "
                                    f"last SCLK rising edge (t_HD.CS >= {tm.t_hd_cs:.0f} ns)")
            if self._min_low < tm.t_low:
                self._violate(t_ns, f"SCLK low for {self._min_low:.0f} ns (t_LOW >= "
                                    f"{tm.t_low:.0f})")
            if self._min_high < tm.t_high:
                self._violate(t_ns, f"SCLK high for {self._min_high:.0f} ns (t_HIGH >= "
                                    f"{tm.t_high:.0f})")
            sensor = (self._read and self._addr is not None
                      and SENSOR_REGS[0] <= self._addr
                      and self._addr + nbytes - 2 <= SENSOR_REGS[1])
            limit = tm.sclk_min_period_sensor if sensor else tm.sclk_min_period
            if self._min_period < limit:
                self._violate(t_ns, f"SCLK period {self._min_period:.0f} ns (min "
                                    f"{limit:.0f} ns)")
        self.stats.transactions += 1
        if self.keep_log:
            self.log.append((self._addr, self._read, bytes(self._line_bytes)))
        if self.fault == "absent":  # no part: nothing is read, no sample is consumed
            pass
        elif self._addr is not None and self._read:
            if self._addr == REG["WHO_AM_I"] and nbytes >= 2:
                self.stats.who_am_i_reads += 1
            if self._addr == REG["ACCEL_XOUT_H"] and nbytes >= 1 + BURST_LEN:
                self.stats.bursts += 1
                self.stats.underruns += self._exhausted
                self._load_next()
        self._reset_transaction()
        self._miso = 0
