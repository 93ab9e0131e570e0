"""Driving TinyKalman with IMU data: log -> MPU-6500 words, synthetic motion, model and RTL
runs (used by ``navgate tinykalman`` and the tests).

Words: the MPU-6500 at its power-on full scales (ACCEL_FS_SEL = 0: 16384 LSB/g, GYRO_FS_SEL = 0:
131 LSB/(deg/s); the chip writes no configuration register), rounded to the nearest LSB and
saturated (counted), :mod:`navgate.devices.mpu6500`. Axes: the part's own (x, y, z with +1 g on
z when it lies flat, face up), which is how x-io style logs record them; logs in FRD body axes
(level: -1 g on z) are turned into the part's axes by (x, -y, -z). One log row is one sample
period of the chip (the ``>>> 6`` rate scaling assumes 100 Hz; the log's own rate is reported,
not resampled). Temperature is not in the logs: 25 degC.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navgate.devices.mpu6500 import BURST_WORDS, encode_accel, encode_gyro, encode_temp
from navgate.nav import validate
from navgate.sim.imu_log import G0

__all__ = ["Words", "words_from_imu", "synthetic_motion", "model_stream", "AXES"]

AXES = ("auto", "flu", "frd")
TEMP_C = 25.0


@dataclass
class Words:
    """Seven int16 words per sample (:data:`BURST_WORDS` order) and the saturation count."""

    words: np.ndarray  #: (N, 7) int64
    saturated: int

    def __len__(self) -> int:
        return len(self.words)

    def column(self, name: str) -> np.ndarray:
        return self.words[:, BURST_WORDS.index(name)]

    def bursts(self) -> list[tuple[int, ...]]:
        return [tuple(int(v) for v in row) for row in self.words]


def words_from_imu(acc_ms2, gyro_rad_s, frd: bool = False) -> Words:
    """Accelerometer (m/s^2) and gyro (rad/s) arrays (N, 3) -> MPU-6500 words.

    NaN/inf or a wrong shape is a ValueError naming the argument; a finite value beyond the
    part's full scale (even 1e300) saturates its word and is counted (:attr:`Words.saturated`),
    as the real part clips."""
    acc = validate.finite_array("acc_ms2", acc_ms2, (-1, 3)) / G0
    dps = np.degrees(validate.finite_array("gyro_rad_s", gyro_rad_s, (-1, 3)))
    if acc.shape != dps.shape:
        raise ValueError(f"gyro_rad_s: {len(dps)} samples, acc_ms2 has {len(acc)}")
    frd = validate.flag("frd", frd)
    if frd:
        flip = np.array([1.0, -1.0, -1.0])
        acc, dps = acc * flip, dps * flip
    n = len(acc)
    out = np.empty((n, 7), dtype=np.int64)
    sat = 0
    temp, _ = encode_temp(TEMP_C)
    for k in range(n):
        row = []
        for v in acc[k]:
            w, s = encode_accel(v)
            row.append(w)
            sat += s
        row.append(temp)
        for v in dps[k]:
            w, s = encode_gyro(v)
            row.append(w)
            sat += s
        out[k] = row
    return Words(out, sat)


def synthetic_motion(n: int, seed: int = 0, rate_hz: float = 100.0) -> Words:
    """Seeded synthetic motion through every attitude region the chip handles.

    Roll sweeps through +-180 deg (upside down, so the filter wraps), pitch through +-80 deg,
    with sinusoids of a few tenths of a Hz, gyro = Euler-angle rates (deg/s) plus white noise,
    specific force = gravity in body axes (+1 g on z when level) plus linear-acceleration
    shocks of 2.2 g on y and z (accelerometer words and mag_yz saturate), and 0.01 g
    noise.
    """
    n = validate.positive_int("n", n)
    rate_hz = validate.positive("rate_hz", rate_hz)
    seed = validate.integer("seed", seed, 0)
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate_hz
    roll = np.radians(200.0 * np.sin(2 * math.pi * 0.05 * t) + 20 * np.sin(2 * math.pi * 0.7 * t))
    pitch = np.radians(80.0 * np.sin(2 * math.pi * 0.031 * t + 0.4))
    d_roll = np.gradient(roll, t) if n > 1 else np.zeros(n)
    d_pitch = np.gradient(pitch, t) if n > 1 else np.zeros(n)
    # gravity in the part's axes for roll phi, pitch theta (z up when level)
    acc = np.stack([-np.sin(pitch), np.cos(pitch) * np.sin(roll), np.cos(pitch) * np.cos(roll)],
                   axis=1)
    # shocks: 1 s in every 7.7 s, 2.2 g on y and z (signs cycling), saturating the words
    bursts = np.sin(2 * math.pi * 0.13 * t) > 0.9
    k = np.floor(0.13 * t).astype(np.int64)
    shock = np.stack([np.zeros(n), 2.2 * np.where(k % 2, -1.0, 1.0),
                      2.2 * np.where((k // 2) % 2, -1.0, 1.0)], axis=1)
    acc = acc + np.where(bursts[:, None], shock, 0.0) + rng.normal(0, 0.01, (n, 3))
    gyro = np.stack([d_roll, d_pitch, np.zeros(n)], axis=1) + rng.normal(0, np.radians(0.5),
                                                                          (n, 3))
    return words_from_imu(acc * G0, gyro)


def model_stream(words: Words) -> bytes:
    """The UART byte stream of the integer model for a word sequence (good sensor)."""
    if not isinstance(words, Words):
        raise ValueError(f"words: expected a Words, got {type(words).__name__}")
    from navgate.systems.tinykalman.model import encode_packet, run_sequence

    roll, pitch, _, _ = run_sequence(words.column("ax"), words.column("ay"),
                                     words.column("az"), words.column("gx"), words.column("gy"))
    return b"".join(encode_packet(int(r), int(p)) for r, p in zip(roll, pitch, strict=True))
