"""Benewake TF-Luna lidar (and the long-range ranger sharing its frame): UART format, the
9-byte data frame, encoder/decoder, and a bit-level UART source for testbenches.

Source: Benewake TF-Luna product manual (as remembered, docs/sensors.md marks what to check):
UART 115200 baud, 8 data bits, no parity, 1 stop bit, LSB first, idle high; default frame rate
100 Hz; the data frame is

    0x59 0x59 Dist_L Dist_H Amp_L Amp_H Temp_L Temp_H Checksum

with the distance in cm (default unit), the signal strength ``Amp``, the chip temperature
``Temp / 8 - 256`` degC and the checksum the low byte of the sum of the first eight bytes. A
strength below 100 or equal to 65535 (overexposure) makes the distance unreliable (the part
then reports distance 0). navgate's long-range ranger (seeds README: same frame family, longer
range) sends the same frame with the distance in decimetres (:data:`LONG_RANGE_UNIT_M`), a
navgate assumption, since 1500 m does not fit 16 bits of centimetres.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

HEADER = 0x59
FRAME_BYTES = 9
BAUD = 115200
DATA_BITS, STOP_BITS = 8, 1
FRAME_RATE_HZ = 100.0
STRENGTH_MIN = 100
STRENGTH_OVEREXPOSED = 65535
UNIT_M = 0.01  #: TF-Luna default: centimetres
LONG_RANGE_UNIT_M = 0.1  #: navgate's long-range ranger: decimetres (assumption)
#: receivers must accept this baud-rate mismatch (+-2 % is the usual 16x-oversampling margin)
BAUD_TOLERANCE = 0.02


def encode_frames(distance_m, strength, temp_c=25.0, unit_m: float = UNIT_M) -> np.ndarray:
    """(N, 9) uint8 frames. NaN or out-of-range distances encode as 0 (no return)."""
    d = np.asarray(distance_m, float)
    n = d.size
    dist = np.where(np.isfinite(d), np.rint(np.nan_to_num(d) / unit_m), 0)
    dist = np.clip(dist, 0, 0xFFFF).astype(np.int64).reshape(n)
    amp = np.broadcast_to(np.asarray(strength, np.int64), (n,)) & 0xFFFF
    temp = np.broadcast_to(np.rint((np.asarray(temp_c, float) + 256.0) * 8).astype(np.int64),
                           (n,)) & 0xFFFF
    f = np.zeros((n, FRAME_BYTES), np.int64)
    f[:, 0] = f[:, 1] = HEADER
    f[:, 2], f[:, 3] = dist & 0xFF, dist >> 8
    f[:, 4], f[:, 5] = amp & 0xFF, amp >> 8
    f[:, 6], f[:, 7] = temp & 0xFF, temp >> 8
    f[:, 8] = f[:, :8].sum(axis=1) & 0xFF
    return f.astype(np.uint8)


def frame_checksum(frames) -> np.ndarray:
    return np.asarray(frames, np.int64)[..., :8].sum(axis=-1) & 0xFF


def decode_frames(frames, unit_m: float = UNIT_M) -> dict[str, np.ndarray]:
    """(N, 9) bytes -> distance (m), strength, temperature (degC), header/checksum/reliable."""
    f = np.asarray(frames, np.int64)
    dist = f[:, 2] | (f[:, 3] << 8)
    amp = f[:, 4] | (f[:, 5] << 8)
    temp = f[:, 6] | (f[:, 7] << 8)
    return {
        "dist_raw": dist, "distance_m": dist * unit_m, "strength": amp,
        "temp_c": temp / 8.0 - 256.0,
        "header_ok": (f[:, 0] == HEADER) & (f[:, 1] == HEADER),
        "checksum_ok": frame_checksum(f) == f[:, 8],
        "reliable": (amp >= STRENGTH_MIN) & (amp != STRENGTH_OVEREXPOSED),
    }


def strength_reliable(strength) -> np.ndarray:
    s = np.asarray(strength, np.int64)
    return (s >= STRENGTH_MIN) & (s != STRENGTH_OVEREXPOSED)


# ---- UART source ---------------------------------------------------------------------------

FAULTS = ("bad_checksum", "drop", "truncate", "noise", "framing_error")


@dataclass
class LidarStream:
    """Frames to send (N, 9), one per frame period, with per-frame faults.

    Faults: ``bad_checksum`` (checksum byte + 1), ``drop`` (frame not sent), ``truncate``
    (only the first 5 bytes sent), ``noise`` (3 random bytes sent before the frame, at least
    one of them 0x59), ``framing_error`` (byte 4 sent with a 0 stop bit).
    """

    frames: np.ndarray
    faults: dict[int, str] = field(default_factory=dict)
    seed: int = 0

    def __post_init__(self):
        self.frames = np.asarray(self.frames, np.uint8)
        for k, f in self.faults.items():
            if f not in FAULTS:
                raise ValueError(f"unknown TF-Luna fault {f!r} at frame {k}")

    def byte_plan(self):
        """Per frame: list of (byte, stop_bit) to send."""
        rng = np.random.default_rng(self.seed)
        plan = []
        for k, frame in enumerate(self.frames):
            fault = self.faults.get(k)
            b = [(int(x), 1) for x in frame]
            if fault == "bad_checksum":
                b[8] = ((b[8][0] + 1) & 0xFF, 1)
            elif fault == "drop":
                b = []
            elif fault == "truncate":
                b = b[:5]
            elif fault == "noise":
                noise = [int(x) for x in rng.integers(0, 256, 3)]
                noise[int(rng.integers(0, 3))] = HEADER
                b = [(x, 1) for x in noise] + b
            elif fault == "framing_error":
                b[4] = (b[4][0], 0)
            plan.append(b)
        return plan

    def expected(self):
        """Indices of the frames a correct receiver delivers (checksum-good, sent whole)."""
        return [k for k in range(len(self.frames))
                if self.faults.get(k) in (None, "noise")]


def uart_transitions(bytes_and_stops, t0: float, bit_time: float):
    """Line levels for consecutive characters starting at ``t0``: list of (time, level), and
    the end time. Each character: start bit (0), 8 data bits LSB first, stop bit."""
    out = []
    t = t0
    level = 1
    for byte, stop in bytes_and_stops:
        bits = [0] + [(byte >> i) & 1 for i in range(DATA_BITS)] + [stop]
        for b in bits:
            if b != level:
                out.append((t, b))
                level = b
            t += bit_time
        if level != 1:  # a 0 stop bit: return the line to idle after the character
            out.append((t, 1))
            level = 1
            t += bit_time
    return out, t


def stream_transitions(stream: LidarStream, baud: float = BAUD, frame_period: float | None
                       = None, t0: float = 0.0):
    """(time, level) transitions of the whole stream: frame k starts at t0 + k*frame_period
    (default: the 9 bytes plus 3 idle character times)."""
    bit = 1.0 / baud
    char = bit * (1 + DATA_BITS + STOP_BITS)
    period = frame_period or char * (FRAME_BYTES + 3 + 3)
    out = []
    for k, plan in enumerate(stream.byte_plan()):
        start = t0 + k * period
        if plan and len(plan) * char + 2 * bit > period:
            raise ValueError("frame period too short for the bytes of a frame")
        tr, _ = uart_transitions(plan, start, bit)
        out.extend(tr)
    return out, t0 + len(stream.frames) * period
