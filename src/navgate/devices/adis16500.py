"""Analog Devices ADIS16500 six-axis IMU: register map, burst read, word scaling, SPI timing,
and a bit-level SPI slave model for testbenches.

Sources: seed 000 ("IMU Interface": 400 Hz burst read, CPOL=1/CPHA=1, the port list's LSB
sizes) and the ADIS16500 data sheet (Rev. B as remembered: "Burst Read Function", register map,
Table 2 timing). The data sheet could not be re-read in the development environment; figures
marked *(check)* below and in docs/sensors.md are from memory and plausible for the part family
(ADIS1650x), not verified against the current revision.

Where the seed and the data sheet differ, the data sheet wins (docs/sensors.md):

* The burst response (16-bit burst, ``MSC_CTRL`` BURST_SEL=0) is DIAG_STAT, X/Y/Z_GYRO_OUT,
  X/Y/Z_ACCL_OUT, TEMP_OUT, DATA_CNTR and a checksum: ten words after the 0x6800 command, not
  the seed's seven. The checksum is the 16-bit sum of the 18 bytes of the nine words before it.
* Burst reads run at most at 1 MHz SCLK *(check)* (register reads 2 MHz); the seed's 2 MHz
  burst clock violates it, so navgate's default divider gives 1 MHz.
* The ADIS16500's gyro LSB is 0.1 deg/s (+-2000 deg/s, 16-bit) *(check)*. Seed 000 writes
  0.00625 deg/s (160 LSB per deg/s, the +-125 deg/s grade of the ADIS16505-1). navgate keeps
  the seed's figure in :data:`GYRO_LSB_RAD_S` because the simulator's default flight and its
  published figures are built on it (a 16x coarser LSB would add quantisation noise to every
  flight); :data:`DATASHEET_GYRO_LSB_RAD_S` holds the part's value. The accelerometer LSB,
  1.25 mg (800 LSB/g, +-40 g), agrees with the data sheet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .spi import SpiSlave, SpiTiming

#: standard gravity, the "g" of the data sheet's mg figures (m/s^2)
STANDARD_GRAVITY = 9.80665
#: seed 000 gyro LSB (rad/s per LSB): 0.00625 deg/s (see the module docstring)
GYRO_LSB_RAD_S = 0.00625 * math.pi / 180.0
#: the ADIS16500 data sheet's 16-bit gyro LSB, 0.1 deg/s (check)
DATASHEET_GYRO_LSB_RAD_S = 0.1 * math.pi / 180.0
#: accelerometer LSB (m/s^2 per LSB): 1.25 mg, seed and data sheet agree
ACCEL_LSB_M_S2 = 1.25e-3 * STANDARD_GRAVITY
#: TEMP_OUT scaling: 0.1 degC per LSB, 0 at 0 degC (check)
TEMP_LSB_C = 0.1
#: range of a 16-bit output word
INT16_MIN, INT16_MAX = -32768, 32767

# ---- register map (byte addresses of the 16-bit registers; data sheet Table "User Register
#      Memory Map") ---------------------------------------------------------------------------
REG = {
    "DIAG_STAT": 0x02, "X_GYRO_LOW": 0x04, "X_GYRO_OUT": 0x06, "Y_GYRO_LOW": 0x08,
    "Y_GYRO_OUT": 0x0A, "Z_GYRO_LOW": 0x0C, "Z_GYRO_OUT": 0x0E, "X_ACCL_LOW": 0x10,
    "X_ACCL_OUT": 0x12, "Y_ACCL_LOW": 0x14, "Y_ACCL_OUT": 0x16, "Z_ACCL_LOW": 0x18,
    "Z_ACCL_OUT": 0x1A, "TEMP_OUT": 0x1C, "TIME_STAMP": 0x1E, "DATA_CNTR": 0x22,
    "FILT_CTRL": 0x5C, "RANG_MDL": 0x5E, "MSC_CTRL": 0x60, "UP_SCALE": 0x62,
    "DEC_RATE": 0x64, "NULL_CNFG": 0x66, "GLOB_CMD": 0x68, "FIRM_REV": 0x6C,
    "FIRM_DM": 0x6E, "FIRM_Y": 0x70, "PROD_ID": 0x72, "SERIAL_NUM": 0x74,
}
#: PROD_ID reads 16500 (0x4074)
PROD_ID = 16500
#: the burst read command: a read of address 0x68 (GLOB_CMD) with the R/W bit clear
BURST_CMD = 0x6800
#: words shifted out after the command (16-bit burst)
BURST_FIELDS = ("diag_stat", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z",
                "temp", "data_cntr", "checksum")
BURST_WORDS = len(BURST_FIELDS)  # 10
#: DIAG_STAT bits (data sheet "Status/Error Flag Indicators")
DIAG_BITS = {"data_path_overrun": 1, "flash_update_failure": 2, "spi_error": 3,
             "standby": 4, "sensor_failure": 5, "memory_failure": 6, "clock_error": 7}
#: internal output data rate before decimation (Hz)
ODR_HZ = 2000.0

#: SPI timing (data sheet Table 2; mode 3). Burst reads use f_sclk_max = 1 MHz (check).
SPI_MODE = 3  # CPOL=1, CPHA=1
SCLK_MAX_HZ = 2.0e6
BURST_SCLK_MAX_HZ = 1.0e6
T_CS_SETUP = 200e-9  #: tCS, CS_N falling to first SCLK edge
T_CS_HOLD = 0.0  #: tSFS, CS_N rising after the last SCLK edge
T_STALL = 16e-6  #: tSTALL, CS_N high between transfers
T_MOSI_SETUP = 25e-9  #: tDSU
T_MOSI_HOLD = 50e-9  #: tDHD
T_MISO_VALID = 100e-9  #: tDAV, MISO valid after SCLK falling edge (the master's concern)
BURST_TIMING = SpiTiming(
    f_sclk_max=BURST_SCLK_MAX_HZ, t_sclk_high_min=0.5 / BURST_SCLK_MAX_HZ * 0.8,
    t_sclk_low_min=0.5 / BURST_SCLK_MAX_HZ * 0.8, t_cs_setup_min=T_CS_SETUP,
    t_cs_hold_min=T_CS_HOLD, t_cs_high_min=T_STALL, t_mosi_setup_min=T_MOSI_SETUP,
    t_mosi_hold_min=T_MOSI_HOLD,
)
"""Limits the model checks. The high/low minimum times are 40 % of the burst clock period, a
navgate assumption for a duty cycle the data sheet does not state separately *(check)*."""


# ---- word encoding ----------------------------------------------------------------------

def quantize_words(words):
    """Round to the nearest integer word and saturate to int16; returns (int16 array, count)."""
    rounded = np.rint(words)
    saturated = int(np.count_nonzero((rounded < INT16_MIN) | (rounded > INT16_MAX)))
    return np.clip(rounded, INT16_MIN, INT16_MAX).astype(np.int16), saturated


def encode_gyro(rate_rad_s, lsb: float = GYRO_LSB_RAD_S):
    """Angular rate (rad/s) -> int16 words (rounded, saturated); returns (words, saturated)."""
    return quantize_words(np.asarray(rate_rad_s, float) / lsb)


def encode_accel(accel_m_s2, lsb: float = ACCEL_LSB_M_S2):
    """Specific force (m/s^2) -> int16 words (rounded, saturated); returns (words, saturated)."""
    return quantize_words(np.asarray(accel_m_s2, float) / lsb)


def decode_gyro(words, lsb: float = GYRO_LSB_RAD_S):
    return np.asarray(words, np.int64).astype(float) * lsb


def decode_accel(words, lsb: float = ACCEL_LSB_M_S2):
    return np.asarray(words, np.int64).astype(float) * lsb


def encode_temp(temp_c):
    return quantize_words(np.asarray(temp_c, float) / TEMP_LSB_C)[0]


def decode_temp(words):
    return np.asarray(words, np.int64).astype(float) * TEMP_LSB_C


def checksum(words) -> np.ndarray:
    """Burst checksum of (..., 9) words (DIAG_STAT .. DATA_CNTR): the 16-bit sum of the bytes."""
    w = np.asarray(words, np.int64) & 0xFFFF
    return ((w & 0xFF).sum(axis=-1) + (w >> 8).sum(axis=-1)) & 0xFFFF


def burst_words(gyro, accel, temp=0, diag=0, cntr=0) -> np.ndarray:
    """The ten 16-bit words (uint16 patterns) of bursts: arrays broadcast over samples.

    ``gyro`` and ``accel`` are (..., 3) int16 words, ``temp`` TEMP_OUT words, ``diag`` the
    DIAG_STAT bits and ``cntr`` DATA_CNTR (taken modulo 2**16). Returns shape (..., 10).
    """
    g = np.asarray(gyro, np.int64)
    a = np.asarray(accel, np.int64)
    shape = np.broadcast_shapes(g.shape[:-1], a.shape[:-1], np.shape(temp), np.shape(diag),
                                np.shape(cntr))
    out = np.zeros(shape + (BURST_WORDS,), np.int64)
    out[..., 0] = np.asarray(diag, np.int64) & 0xFFFF
    out[..., 1:4] = g & 0xFFFF
    out[..., 4:7] = a & 0xFFFF
    out[..., 7] = np.asarray(temp, np.int64) & 0xFFFF
    out[..., 8] = np.asarray(cntr, np.int64) & 0xFFFF
    out[..., 9] = checksum(out[..., :9])
    return out.astype(np.uint16)


def decode_burst(words) -> dict[str, np.ndarray]:
    """(..., 10) burst words -> fields (signed for the outputs) and ``checksum_ok``."""
    w = np.asarray(words, np.int64) & 0xFFFF

    def s16(x):
        return np.where(x >= 0x8000, x - 0x10000, x)

    return {
        "diag_stat": w[..., 0], "gyro": s16(w[..., 1:4]), "accel": s16(w[..., 4:7]),
        "temp": s16(w[..., 7]), "data_cntr": w[..., 8], "checksum": w[..., 9],
        "checksum_ok": checksum(w[..., :9]) == w[..., 9],
    }


# ---- bit-level device model --------------------------------------------------------------

FAULTS = ("bad_checksum", "stuck_low", "stuck_high", "missing")


@dataclass
class ImuStream:
    """What the model serves: one burst per sample (int16 words), in order."""

    gyro: np.ndarray  #: (N, 3) int16 words
    accel: np.ndarray  #: (N, 3)
    temp: np.ndarray | None = None  #: (N,) TEMP_OUT words (default 25 degC)
    diag: np.ndarray | None = None  #: (N,) DIAG_STAT (default 0)
    faults: dict[int, str] = field(default_factory=dict)  #: sample index -> fault

    def __post_init__(self):
        n = len(self.gyro)
        self.gyro = np.asarray(self.gyro, np.int64)
        self.accel = np.asarray(self.accel, np.int64)
        self.temp = np.full(n, 250) if self.temp is None else np.asarray(self.temp, np.int64)
        self.diag = np.zeros(n, np.int64) if self.diag is None else np.asarray(self.diag)
        for k, f in self.faults.items():
            if f not in FAULTS:
                raise ValueError(f"unknown ADIS16500 fault {f!r} at sample {k}; "
                                 f"known: {', '.join(FAULTS)}")
        self.words = burst_words(self.gyro, self.accel, self.temp, self.diag,
                                 np.arange(n) + 1)


class Adis16500Model(SpiSlave):
    """ADIS16500 SPI slave (mode 3, 16-bit words) serving :class:`ImuStream` samples.

    Each burst (command 0x6800) delivers the next sample of the stream; DATA_CNTR counts the
    samples from 1. Non-burst reads (R/W bit 15 clear, address in bits 14:8) answer in the
    next 16-bit frame (PROD_ID and the burst fields; other registers read 0); writes (bit 15
    set) are stored. Faults, per sample index: ``bad_checksum`` (checksum word off by one),
    ``stuck_low``/``stuck_high`` (MISO held for the whole burst), ``missing`` (no device: MISO
    floats to the pull-up, same as stuck high). Every data-sheet timing violation is recorded
    in :attr:`violations` (:class:`navgate.devices.spi.SpiSlave`).
    """

    WORD_BITS = 16
    timing = BURST_TIMING

    def __init__(self, stream: ImuStream, timing: SpiTiming | None = None):
        super().__init__(timing)
        self.stream = stream
        self.sample = 0  #: index of the next sample to serve
        self.served: list[int] = []  #: sample index of every completed burst
        self._burst = None
        self._pending = 0
        self.registers: dict[int, int] = {REG["PROD_ID"]: PROD_ID}

    def begin(self):
        self._burst = None

    def next_word(self, index):
        if index == 0:
            return self._pending
        if self._burst is not None and index - 1 < BURST_WORDS:
            return int(self._burst[index - 1])
        return self._pending if self._burst is None else 0

    def word(self, index, value):
        if index == 0 and value == BURST_CMD:
            k = min(self.sample, len(self.stream.words) - 1)
            words = self.stream.words[k].astype(np.int64).copy()
            fault = self.stream.faults.get(k)
            if fault == "bad_checksum":
                words[9] = (words[9] + 1) & 0xFFFF
            self._burst = words
            self._stuck = {"stuck_low": 0, "stuck_high": 1, "missing": 1}.get(fault)
            self._pending = 0
            return
        if self._burst is not None:
            return  # words clocked in during a burst are ignored
        addr = (value >> 8) & 0x7F
        if value & 0x8000:  # write: one byte of a register
            base = addr & 0x7E
            old = self.registers.get(base, 0)
            if addr & 1:
                self.registers[base] = (old & 0x00FF) | ((value & 0xFF) << 8)
            else:
                self.registers[base] = (old & 0xFF00) | (value & 0xFF)
            self._pending = 0
        else:
            self._pending = self._register(addr & 0x7E)

    def _register(self, addr):
        k = min(self.sample, len(self.stream.words) - 1)
        w = self.stream.words[k]
        field_at = {REG["DIAG_STAT"]: 0, REG["X_GYRO_OUT"]: 1, REG["Y_GYRO_OUT"]: 2,
                    REG["Z_GYRO_OUT"]: 3, REG["X_ACCL_OUT"]: 4, REG["Y_ACCL_OUT"]: 5,
                    REG["Z_ACCL_OUT"]: 6, REG["TEMP_OUT"]: 7, REG["DATA_CNTR"]: 8}
        if addr in field_at:
            return int(w[field_at[addr]])
        return self.registers.get(addr, 0)

    def end(self, bits):
        if self._burst is not None and bits >= 16 * (BURST_WORDS + 1):
            self.served.append(self.sample)
            self.sample += 1
        self._burst = None
        self._stuck = None
