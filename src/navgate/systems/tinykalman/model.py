"""Seed 001, TinyKalman: integer bit-true model of the MPU-6500 -> CORDIC -> steady-state
Kalman -> UART chain.

Reference: seed 001 (TinyKalman on TinyTapeout: "Angle Estimation (CORDIC)", "Sensor Fusion",
"Data Format"); the upstream design the seed documents (github.com/intv0id/tt-ihp-TinyKalman,
``src/cordic.v``, ``src/kalman.v``, ``src/project.v``), consulted for facts the seed leaves out:
16 CORDIC stages at 16 bits (the ``cordic`` module's defaults), roll inputs halved before the
CORDIC, pitch's y input scaled by 0.8125 ~ K/2; InvenSense MPU-6500 Register Map and
Descriptions (RM-MPU-6500A-00 rev 2.1) and Product Specification (PS-MPU-6500A-01 rev 1.1)
for registers and sensitivities.

Datapath (all integers; ``>>>`` is the arithmetic shift, floor):

* Sensor words: big-endian int16 from the 14-byte burst at ACCEL_XOUT_H (0x3B):
  ax, ay, az, temperature, gx, gy, gz (:func:`decode_burst`).
* Roll: ``(mag_yz, roll_m) = CORDIC(x = az >>> 1, y = ay >>> 1)``, i.e. atan2(ay, az);
  ``mag_yz = K_16 |(az, ay)| / 2`` (gain not removed).
* Pitch (the seed's magnitude approximation): ``pitch_m = CORDIC(x = mag_yz,
  y = -((ax >>> 1) + (ax >>> 2) + (ax >>> 4)))``: the roll CORDIC's magnitude stands in for
  sqrt(ay^2 + az^2) and ax is pre-scaled by 0.8125 ~ K_16 / 2 = 0.8234 so both inputs carry
  about the same gain. ``mag_yz`` is saturated to the 16-bit input range (counted).
* CORDIC: :func:`navgate.numerics.cordic.cordic_vectoring` with ``width=16``,
  ``iterations=16``, ``angle_bits=16`` (32768 = 180 deg). The upstream Verilog differs in two
  details that only matter for |angle| > 90 deg or in the last LSBs: its table entry 3 is
  1297 (navgate's rounded table: 1298) and it pre-rotates x < 0 by 180 deg (navgate: +-90 deg,
  exact). navgate keeps the shared numerics core; docs/seed001-tinykalman.md.
* Filter per axis, 16-bit two's complement wrap-around (binary angles wrap at +-180 deg,
  so the innovation is the shortest angular difference):
  ``pred = angle + (rate >>> 6)``; ``angle = pred + ((meas - pred) >>> 6)``.
  Roll uses gyro x, pitch gyro y (upstream ``S_UPDATE_K``).
* UART packet: 6 bytes ``DE AD roll_hi roll_lo pitch_hi pitch_lo`` (:func:`encode_packet`),
  8N1 frames LSB first at 9600 baud (:func:`uart_frame_bits`). The seed's prose says
  8-byte packets but its table lists 6 bytes and the upstream FSM sends 6 (``uart_cnt``
  0..5): navgate uses 6; a packet then takes 6 * 10 / 9600 = 6.25 ms, inside the 10 ms
  period of the 100 Hz loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from navgate.numerics.cordic import cordic_vectoring

# ------------------------------------------------------------------------------- MPU-6500

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
WHO_AM_I_VALUE = 0x70  #: MPU-6500's WHO_AM_I reset value
SPI_READ = 0x80  #: bit 7 of the address byte: 1 = read
BURST_LEN = 14  #: ACCEL_XOUT_H .. GYRO_ZOUT_L

#: LSB per (deg/s) for GYRO_CONFIG.GYRO_FS_SEL = 0..3 (+-250, 500, 1000, 2000 deg/s)
GYRO_SENSITIVITY = (131.0, 65.5, 32.8, 16.4)
#: LSB per g for ACCEL_CONFIG.ACCEL_FS_SEL = 0..3 (+-2, 4, 8, 16 g)
ACCEL_SENSITIVITY = (16384.0, 8192.0, 4096.0, 2048.0)
TEMP_SENSITIVITY = 333.87  #: LSB per degC
TEMP_OFFSET_C = 21.0  #: degC at TEMP_OUT = 0 (room-temperature offset 0)


def _to_word(value: float) -> tuple[int, bool]:
    """Round to the nearest int16, saturating; returns (word, saturated)."""
    if not math.isfinite(value):
        raise ValueError("sensor value must be finite")
    w = int(round(value))
    sat = w > 32767 or w < -32768
    return max(-32768, min(32767, w)), sat


class Mpu6500:
    """Register-level MPU-6500 model on SPI: writes configure, reads return sensor words.

    ``set_sample`` loads physical values (g, deg/s, degC) into the data registers with the
    configured full scale, rounding to the nearest LSB and saturating (counted in
    ``saturated``). ``transfer`` is one SPI transaction (CS low .. high): the first MOSI
    byte is the address (bit 7 = read), then the device auto-increments.
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

    def set_sample(self, accel_g, gyro_dps, temp_c: float = 25.0) -> None:
        sa = ACCEL_SENSITIVITY[self.accel_fs]
        sg = GYRO_SENSITIVITY[self.gyro_fs]
        for i, v in enumerate(accel_g):
            w, s = _to_word(float(v) * sa)
            self.saturated += s
            self._put(REG["ACCEL_XOUT_H"] + 2 * i, w)
        for i, v in enumerate(gyro_dps):
            w, s = _to_word(float(v) * sg)
            self.saturated += s
            self._put(REG["GYRO_XOUT_H"] + 2 * i, w)
        w, s = _to_word((temp_c - TEMP_OFFSET_C) * TEMP_SENSITIVITY)
        self.saturated += s
        self._put(REG["TEMP_OUT_H"], w)

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
                out.append(self.regs[a])
            elif a != REG["WHO_AM_I"]:  # read-only
                self.regs[a] = byte & 0xFF
                out.append(0)
            else:
                out.append(0)
        return bytes(out)

    def read_burst(self) -> bytes:
        """The driver's 14-byte burst from ACCEL_XOUT_H."""
        return self.transfer(bytes([SPI_READ | REG["ACCEL_XOUT_H"]]) + bytes(BURST_LEN))[1:]


def decode_burst(burst: bytes) -> dict[str, int]:
    """14 burst bytes -> signed words ax, ay, az, temp, gx, gy, gz (big-endian int16)."""
    if len(burst) != BURST_LEN:
        raise ValueError(f"an MPU-6500 burst is {BURST_LEN} bytes, got {len(burst)}")
    words = [int.from_bytes(burst[i:i + 2], "big", signed=True) for i in range(0, 14, 2)]
    return dict(zip(("ax", "ay", "az", "temp", "gx", "gy", "gz"), words, strict=True))


# ------------------------------------------------------------------------------- angles

WIDTH = 16
ITERATIONS = 16
ANGLE_BITS = 16
BAM_PER_DEG = 2**ANGLE_BITS / 360.0  #: 32768 = 180 deg


def _wrap16(v):
    """Keep the low 16 bits as two's complement (what a 16-bit Verilog wire holds)."""
    v = np.asarray(v, dtype=np.int64)
    return ((v + 32768) & 0xFFFF) - 32768


def accel_angles(ax, ay, az):
    """(roll_m, pitch_m, mag_yz, mag_saturated) binary angles from accelerometer words.

    Vectorised over arrays of int16 words.
    """
    ax = np.asarray(ax, dtype=np.int64)
    ay = np.asarray(ay, dtype=np.int64)
    az = np.asarray(az, dtype=np.int64)
    mag, roll = cordic_vectoring(az >> 1, ay >> 1, WIDTH, ITERATIONS, angle_bits=ANGLE_BITS)
    mag = np.asarray(mag)
    sat = mag > 32767
    mag_in = np.minimum(mag, 32767)
    ax_scaled = (ax >> 1) + (ax >> 2) + (ax >> 4)
    _, pitch = cordic_vectoring(mag_in, -ax_scaled, WIDTH, ITERATIONS, angle_bits=ANGLE_BITS)
    return np.asarray(roll), np.asarray(pitch), mag, sat


def kalman_step(angle, rate, meas, rate_shift: int = 6, k_shift: int = 6):
    """One steady-state Kalman update on 16-bit words (vectorised)."""
    angle = np.asarray(angle, dtype=np.int64)
    pred = _wrap16(angle + (np.asarray(rate, dtype=np.int64) >> rate_shift))
    innov = _wrap16(np.asarray(meas, dtype=np.int64) - pred)
    return _wrap16(pred + (innov >> k_shift))


# ------------------------------------------------------------------------------- UART

HEADER = b"\xde\xad"
PACKET_LEN = 6
BAUD = 9600


def encode_packet(roll: int, pitch: int) -> bytes:
    """DE AD roll(big-endian int16) pitch(big-endian int16)."""
    for name, v in (("roll", roll), ("pitch", pitch)):
        if not -32768 <= int(v) <= 32767:
            raise ValueError(f"{name} {v} does not fit a signed 16-bit word")
    return HEADER + int(roll).to_bytes(2, "big", signed=True) + int(pitch).to_bytes(
        2, "big", signed=True)


@dataclass
class DecodeStats:
    packets: int = 0
    skipped_bytes: int = 0  #: bytes discarded while searching for a header
    trailing_bytes: int = 0  #: an incomplete packet at the end of the stream


@dataclass
class PacketDecoder:
    """Streaming decoder: feed bytes in any chunking, get (roll, pitch) words back.

    Synchronises on DE AD; bytes before a header are skipped and counted. Because angle
    bytes may themselves contain DE AD, a false lock is possible after a dropped byte; the
    decoder re-checks the header of every packet, so a false lock costs at most the bytes up
    to the next true header (counted as skipped).
    """

    stats: DecodeStats = field(default_factory=DecodeStats)
    _buf: bytearray = field(default_factory=bytearray)

    def feed(self, data: bytes) -> list[tuple[int, int]]:
        self._buf += data
        out = []
        while True:
            i = self._buf.find(HEADER)
            if i < 0:
                # keep a trailing 0xDE: it may start the next header
                keep = 1 if self._buf[-1:] == HEADER[:1] else 0
                self.stats.skipped_bytes += len(self._buf) - keep
                del self._buf[:len(self._buf) - keep]
                break
            self.stats.skipped_bytes += i
            del self._buf[:i]
            if len(self._buf) < PACKET_LEN:
                break
            pkt = bytes(self._buf[:PACKET_LEN])
            del self._buf[:PACKET_LEN]
            out.append((int.from_bytes(pkt[2:4], "big", signed=True),
                        int.from_bytes(pkt[4:6], "big", signed=True)))
            self.stats.packets += 1
        return out

    def close(self) -> None:
        self.stats.trailing_bytes = len(self._buf)


def decode_stream(data: bytes) -> tuple[list[tuple[int, int]], DecodeStats]:
    """Decode a whole byte stream; returns the (roll, pitch) words and the statistics."""
    dec = PacketDecoder()
    out = dec.feed(data)
    dec.close()
    return out, dec.stats


def uart_frame_bits(data: bytes) -> list[int]:
    """Line levels of 8N1 frames, one entry per bit time: start 0, 8 data bits LSB first,
    stop 1 (what ``uart_tx`` drives)."""
    bits = []
    for byte in data:
        bits.append(0)
        bits.extend((byte >> i) & 1 for i in range(8))
        bits.append(1)
    return bits


def uart_decode_bits(bits) -> bytes:
    """Inverse of :func:`uart_frame_bits` for an ideal line (framing errors raise)."""
    bits = list(bits)
    if len(bits) % 10:
        raise ValueError("8N1 stream length must be a multiple of 10 bit times")
    out = bytearray()
    for k in range(0, len(bits), 10):
        f = bits[k:k + 10]
        if f[0] != 0 or f[9] != 1:
            raise ValueError(f"framing error in frame {k // 10}")
        out.append(sum(b << i for i, b in enumerate(f[1:9])))
    return bytes(out)


# ------------------------------------------------------------------------------- top level


def bam_to_deg(words):
    return np.asarray(words, dtype=np.float64) / BAM_PER_DEG


@dataclass
class TinyKalmanState:
    roll: int = 0
    pitch: int = 0
    mag_saturations: int = 0


class TinyKalman:
    """The whole device: one :meth:`step` per MPU sample (100 Hz) -> UART packet bytes."""

    def __init__(self):
        self.state = TinyKalmanState()

    def step(self, burst: bytes) -> bytes:
        w = decode_burst(burst)
        roll_m, pitch_m, _, sat = accel_angles(w["ax"], w["ay"], w["az"])
        s = self.state
        s.mag_saturations += int(sat)
        s.roll = int(kalman_step(s.roll, w["gx"], int(roll_m)))
        s.pitch = int(kalman_step(s.pitch, w["gy"], int(pitch_m)))
        return encode_packet(s.roll, s.pitch)


def run_sequence(ax, ay, az, gx, gy):
    """Vectorised over time: filter word sequences (int arrays of equal length) and return
    (roll_est, pitch_est, roll_m, pitch_m) arrays. Same arithmetic as :class:`TinyKalman`."""
    roll_m, pitch_m, _, _ = accel_angles(ax, ay, az)
    n = len(roll_m)
    roll = np.empty(n, dtype=np.int64)
    pitch = np.empty(n, dtype=np.int64)
    r = p = 0
    gx = np.asarray(gx, dtype=np.int64)
    gy = np.asarray(gy, dtype=np.int64)
    for k in range(n):
        pr = ((r + (int(gx[k]) >> 6) + 32768) & 0xFFFF) - 32768
        r = ((pr + ((((int(roll_m[k]) - pr + 32768) & 0xFFFF) - 32768) >> 6) + 32768)
             & 0xFFFF) - 32768
        pp = ((p + (int(gy[k]) >> 6) + 32768) & 0xFFFF) - 32768
        p = ((pp + ((((int(pitch_m[k]) - pp + 32768) & 0xFFFF) - 32768) >> 6) + 32768)
             & 0xFFFF) - 32768
        roll[k] = r
        pitch[k] = p
    return roll, pitch, np.asarray(roll_m), np.asarray(pitch_m)
