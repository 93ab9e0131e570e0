"""Attitude estimation: seed 003's Mahony-type attitude-solving circuit (float64 reference and
float32 bit-true model), seed 001's TinyKalman (integer bit-true model and UART packets), a
quaternion complementary filter, and the IMU log reader behind ``navgate ahrs``.

See docs/seed003-attitude.md and docs/seed001-tinykalman.md.
"""
