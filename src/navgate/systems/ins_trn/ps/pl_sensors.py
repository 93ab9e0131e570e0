"""The barometer and the ranger as the PS sees them through the PL (seed 000 "Sensor
Interfaces"): the device side turns the flight's records into the parts' output words, the PL
delivers what its interfaces compute, the PS turns that into the navigator's measurements.

- Barometer: the record's altitude -> ISA pressure -> the BMP390's 24-bit ADC words
  (:func:`navgate.devices.bmp390.encode`, 25 degC, the default calibration NVM) -> the PL's
  float32 compensation (``baro_compensation``; BARO_PRESS) -> the PS's ISA altitude in
  float64. The encoder's rounding and the float32 compensation move the altitude by
  millimetres (docs/sensors-gateware.md bounds both).
- Ranger: the record's slant range -> the Benewake 9-byte frame's distance word in the
  ranger's unit (cm for the TF-Luna, dm for navgate's long-range ranger,
  :data:`navgate.devices.tfluna.LONG_RANGE_UNIT_M`) and strength (1000 for a return, 0 for
  none, as :meth:`navgate.sim.sensors.RangerRecord.frames` encodes them) -> the PL's receiver
  (``uart_rx_lidar``; LIDAR_DATA) -> the PS: reliable when 100 <= strength < 65535, range =
  distance x unit.

The float32 engines (``fp32``, ``rtl``, ``fpga-sim``) model the PL, so the navigator reads
these sensors through them (:attr:`navgate.systems.ins_trn.ps.pl_interface.PlEngine.pl_sensors`);
the float64 reference engine takes the records as they are.
"""

from __future__ import annotations

import math

import numpy as np

from navgate.devices import bmp390, tfluna
from navgate.sim.sensors import isa_altitude, isa_pressure

__all__ = ["BARO_TEMP_C", "RANGE_STRENGTH", "baro_words", "altitude_from_pressure",
           "ranger_unit", "ranger_words", "range_from_words"]

#: the temperature the barometer records are encoded at (degC)
BARO_TEMP_C = 25.0
#: the strength a ranger return is encoded with (no return: 0)
RANGE_STRENGTH = 1000


def baro_words(altitude) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(uncomp_press, uncomp_temp, ok) for the records' altitudes; ``ok`` is False where the
    altitude is not finite or its pressure is outside the part's ADC range."""
    h = np.atleast_1d(np.asarray(altitude, float))
    ok = np.isfinite(h)
    up = np.zeros(h.shape, np.int64)
    ut = np.zeros(h.shape, np.int64)
    if not ok.any():
        return up, ut, ok
    p = isa_pressure(np.where(ok, h, 0.0))
    try:
        up[ok], ut[ok] = bmp390.encode(p[ok], np.full(int(ok.sum()), BARO_TEMP_C))
    except ValueError:  # some pressure outside the ADC range: encode one by one
        for i in np.flatnonzero(ok):
            try:
                a, b = bmp390.encode(p[i:i + 1], np.array([BARO_TEMP_C]))
                up[i], ut[i] = a[0], b[0]
            except ValueError:
                ok[i] = False
    return up, ut, ok


def altitude_from_pressure(p: float) -> float:
    """The PS's ISA altitude (m) for the PL's pressure; NaN for an impossible pressure."""
    return float(isa_altitude(p)) if math.isfinite(p) and p > 0 else math.nan


def ranger_unit(preset: str) -> float:
    """The frame's distance unit (m) of a ranger preset (navgate.sim.sensors.RANGER_PRESETS)."""
    return tfluna.UNIT_M if preset == "tf-luna" else tfluna.LONG_RANGE_UNIT_M


def ranger_words(slant_range: float, valid: bool, unit: float) -> tuple[int, int]:
    """(distance word, strength) of the frame the ranger sends for one record."""
    frame = tfluna.encode_frames(np.array([slant_range if valid else math.nan]),
                                 RANGE_STRENGTH if valid else 0, 25.0, unit)[0]
    return int(frame[2]) | int(frame[3]) << 8, int(frame[4]) | int(frame[5]) << 8


def range_from_words(dist: int, strength: int, unit: float) -> tuple[float, bool]:
    """The PS's (slant range m, valid) from the PL's distance word and strength."""
    reliable = tfluna.STRENGTH_MIN <= strength < tfluna.STRENGTH_OVEREXPOSED
    return (dist * unit if reliable else math.nan), bool(reliable)
