"""Analog Devices ADIS16500 six-axis IMU: output word scaling as seed 000 uses it.

Seed 000 ("IMU Interface") reads 16-bit two's complement gyro and accelerometer words over
an SPI burst and scales them with fixed LSB sizes: 0.00625 deg/s per LSB (gyro) and 1.25 mg
per LSB (accelerometer). These are the seed's figures; docs/sensors.md compares them with the
data sheet.
"""

from __future__ import annotations

import math

#: standard gravity, the "g" of the data sheet's mg figures (m/s^2)
STANDARD_GRAVITY = 9.80665
#: seed 000 gyro LSB (rad/s per LSB): 0.00625 deg/s
GYRO_LSB_RAD_S = 0.00625 * math.pi / 180.0
#: seed 000 accelerometer LSB (m/s^2 per LSB): 1.25 mg
ACCEL_LSB_M_S2 = 1.25e-3 * STANDARD_GRAVITY
#: range of a 16-bit output word
INT16_MIN, INT16_MAX = -32768, 32767
