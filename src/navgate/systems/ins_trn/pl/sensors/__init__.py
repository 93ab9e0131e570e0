"""Seed 000 ``sensor_subsystem`` gateware: ADIS16500 burst reader, BMP390 reader with its
float32 compensation engine, TF-Luna frame receiver, IMU calibration (docs/sensors-gateware.md).
"""
