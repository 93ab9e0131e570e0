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
* Guards (issue 31, :mod:`navgate.nav.validate`): every word argument is an integer that fits
  its 16-bit register (NaN, inf, 2.5 or 40000 is a ``ValueError`` naming the argument,
  never a silent truncation or a 17th bit); the gain shifts are integers in [0, 15] (the
  hardware's :class:`~navgate.systems.tinykalman.datapath.KalmanSteady` limits); the word
  sequences of one call have one length. Overflow *inside* the chain is the chip's own
  behaviour and is counted, not refused: ``mag_yz`` saturation (``mag_saturations``) and
  the MPU words' saturation (:class:`navgate.systems.tinykalman.run.Words.saturated`).
* UART packet: 6 bytes ``DE AD roll_hi roll_lo pitch_hi pitch_lo`` (:func:`encode_packet`),
  8N1 frames LSB first at 9600 baud (:func:`uart_frame_bits`). The seed's prose says
  8-byte packets but its table lists 6 bytes and the upstream FSM sends 6 (``uart_cnt``
  0..5): navgate uses 6; a packet then takes 6 * 10 / 9600 = 6.25 ms, inside the 10 ms
  period of the 100 Hz loop.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from navgate.devices.mpu6500 import (
    ACCEL_SENSITIVITY,
    BURST_LEN,
    GYRO_SENSITIVITY,
    REG,
    SPI_READ,
    TEMP_OFFSET_C,
    TEMP_SENSITIVITY,
    WHO_AM_I_VALUE,
    Mpu6500,
    decode_burst,
)
from navgate.nav import validate
from navgate.numerics.cordic import cordic_vectoring

# The MPU-6500's facts and register model live in navgate.devices.mpu6500 (one place); they are
# re-exported here for the model's users.
__all__ = [
    "ACCEL_SENSITIVITY", "BURST_LEN", "GYRO_SENSITIVITY", "REG", "SPI_READ", "TEMP_OFFSET_C",
    "TEMP_SENSITIVITY", "WHO_AM_I_VALUE", "Mpu6500", "decode_burst", "WIDTH", "ITERATIONS",
    "ANGLE_BITS", "BAM_PER_DEG", "accel_angles", "kalman_step", "HEADER", "PACKET_LEN", "BAUD",
    "encode_packet", "DecodeStats", "PacketDecoder", "decode_stream", "uart_frame_bits",
    "uart_decode_bits", "bam_to_deg", "TinyKalmanState", "TinyKalman", "run_sequence",
    "gain_shift",
]

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

    Vectorised over arrays of int16 words (of one shape).
    """
    ax, ay, az = _words16(ax=ax, ay=ay, az=az)
    mag, roll = cordic_vectoring(az >> 1, ay >> 1, WIDTH, ITERATIONS, angle_bits=ANGLE_BITS)
    mag = np.asarray(mag)
    sat = mag > 32767
    mag_in = np.minimum(mag, 32767)
    ax_scaled = (ax >> 1) + (ax >> 2) + (ax >> 4)
    _, pitch = cordic_vectoring(mag_in, -ax_scaled, WIDTH, ITERATIONS, angle_bits=ANGLE_BITS)
    return np.asarray(roll), np.asarray(pitch), mag, sat


def _words16(**named) -> list[np.ndarray]:
    """Each argument as int16 words (:func:`navgate.nav.validate.int_words`), all of one
    shape (a ValueError naming the first that differs)."""
    words = [validate.int_words(name, v, WIDTH) for name, v in named.items()]
    names = list(named)
    for name, w in zip(names[1:], words[1:], strict=True):
        if w.shape != words[0].shape:
            raise ValueError(f"{name}: shape {w.shape} differs from {names[0]}'s "
                             f"{words[0].shape}")
    return words


def gain_shift(name: str, value) -> int:
    """A shift of the steady-state filter (gain 2^-shift): an integer in [0, 15], as the
    gateware's :class:`~navgate.systems.tinykalman.datapath.KalmanSteady` accepts."""
    return validate.integer(name, value, 0, WIDTH - 1)


def kalman_step(angle, rate, meas, rate_shift: int = 6, k_shift: int = 6):
    """One steady-state Kalman update on 16-bit words (vectorised)."""
    rate_shift = gain_shift("rate_shift", rate_shift)
    k_shift = gain_shift("k_shift", k_shift)
    angle, rate, meas = _words16(angle=angle, rate=rate, meas=meas)
    pred = _wrap16(angle + (rate >> rate_shift))
    innov = _wrap16(meas - pred)
    return _wrap16(pred + (innov >> k_shift))


# ------------------------------------------------------------------------------- UART

HEADER = b"\xde\xad"
PACKET_LEN = 6
BAUD = 9600


def encode_packet(roll: int, pitch: int) -> bytes:
    """DE AD roll(big-endian int16) pitch(big-endian int16)."""
    lo, hi = validate.word_range(WIDTH)
    roll = validate.integer("roll", roll, lo, hi)
    pitch = validate.integer("pitch", pitch, lo, hi)
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
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise ValueError(f"data: expected bytes, got {type(data).__name__}")
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
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise ValueError(f"data: expected bytes, got {type(data).__name__}")
    dec = PacketDecoder()
    out = dec.feed(data)
    dec.close()
    return out, dec.stats


def uart_frame_bits(data: bytes) -> list[int]:
    """Line levels of 8N1 frames, one entry per bit time: start 0, 8 data bits LSB first,
    stop 1 (what ``uart_tx`` drives)."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise ValueError(f"data: expected bytes, got {type(data).__name__}")
    bits = []
    for byte in data:
        bits.append(0)
        bits.extend((byte >> i) & 1 for i in range(8))
        bits.append(1)
    return bits


def uart_decode_bits(bits) -> bytes:
    """Inverse of :func:`uart_frame_bits` for an ideal line (framing errors raise)."""
    bits = list(bits)
    bad = next((k for k, b in enumerate(bits) if isinstance(b, str) or b not in (0, 1)), None)
    if bad is not None:
        raise ValueError(f"bits: a line level is 0 or 1, got {bits[bad]!r} at bit {bad}")
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
    sensor_faults: int = 0  #: samples whose WHO_AM_I check failed (filter held)


class TinyKalman:
    """The whole device: one :meth:`step` per MPU sample (100 Hz) -> UART packet bytes.

    Sensor check (the gateware's, docs/seed001-tinykalman.md "Faults"): every sample period
    the chip reads WHO_AM_I before the burst. When it is not 0x70 (wrong part, device absent,
    MISO stuck) the sample is not used: the filter state is held, the packet repeats the held
    angles, and the chip raises its fault pin (``uio_out[0]``). ``step`` takes the WHO_AM_I
    byte the chip read (default: a good part).
    """

    def __init__(self):
        self.state = TinyKalmanState()

    def step(self, burst: bytes, who_am_i: int = WHO_AM_I_VALUE) -> bytes:
        s = self.state
        who_am_i = validate.integer("who_am_i", who_am_i, 0, 255)  # the byte the chip read
        if not isinstance(burst, (bytes, bytearray, memoryview)):
            raise ValueError(f"burst: expected bytes, got {type(burst).__name__}")
        if who_am_i != WHO_AM_I_VALUE:
            s.sensor_faults += 1
            return encode_packet(s.roll, s.pitch)
        w = decode_burst(burst)
        roll_m, pitch_m, _, sat = accel_angles(w["ax"], w["ay"], w["az"])
        s.mag_saturations += int(sat)
        s.roll = int(kalman_step(s.roll, w["gx"], int(roll_m)))
        s.pitch = int(kalman_step(s.pitch, w["gy"], int(pitch_m)))
        return encode_packet(s.roll, s.pitch)


def run_sequence(ax, ay, az, gx, gy, valid=None):
    """Vectorised over time: filter word sequences (int arrays of equal length) and return
    (roll_est, pitch_est, roll_m, pitch_m) arrays. Same arithmetic as :class:`TinyKalman`;
    ``valid`` (bool array, default all true) marks the samples whose WHO_AM_I check passed,
    the others hold the state."""
    ax, ay, az, gx, gy = _words16(ax=ax, ay=ay, az=az, gx=gx, gy=gy)
    if ax.ndim != 1:
        raise ValueError(f"ax: expected a 1-D sequence of words, got shape {ax.shape}")
    roll_m, pitch_m, _, _ = accel_angles(ax, ay, az)
    n = len(roll_m)
    roll = np.empty(n, dtype=np.int64)
    pitch = np.empty(n, dtype=np.int64)
    r = p = 0
    if valid is None:
        ok = np.ones(n, dtype=bool)
    else:
        ok = np.asarray(valid)
        if ok.dtype != np.bool_:  # 0/1 flags as integers (the gateware's ok bit)
            ok = validate.int_words("valid", ok, 1, signed=False)
        if ok.shape != (n,):
            raise ValueError(f"valid: shape {ok.shape} differs from the words' {(n,)}")
        ok = ok.astype(bool)
    for k in range(n):
        if not ok[k]:
            roll[k] = r
            pitch[k] = p
            continue
        pr = ((r + (int(gx[k]) >> 6) + 32768) & 0xFFFF) - 32768
        r = ((pr + ((((int(roll_m[k]) - pr + 32768) & 0xFFFF) - 32768) >> 6) + 32768)
             & 0xFFFF) - 32768
        pp = ((p + (int(gy[k]) >> 6) + 32768) & 0xFFFF) - 32768
        p = ((pp + ((((int(pitch_m[k]) - pp + 32768) & 0xFFFF) - 32768) >> 6) + 32768)
             & 0xFFFF) - 32768
        roll[k] = r
        pitch[k] = p
    return roll, pitch, np.asarray(roll_m), np.asarray(pitch_m)
