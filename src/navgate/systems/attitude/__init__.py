"""Seed 003: the Mahony-type attitude-solving circuit, and the estimators behind ``navgate ahrs``.

``mahony`` (float64 reference), ``mahony_fp32`` (float32 bit-true model), ``atan16`` (the
seed's fix16 arctangent), ``complementary`` (a quaternion complementary filter) and
``estimate`` (either filter over an IMU log read by :mod:`navgate.sim.imu_log`).

See docs/seed003-attitude.md. Seed 001's TinyKalman is :mod:`navgate.systems.tinykalman`.
"""
