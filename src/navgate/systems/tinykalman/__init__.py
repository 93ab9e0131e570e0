"""Seed 001: TinyKalman, a TinyTapeout attitude chip (docs/seed001-tinykalman.md).

``model``: the integer bit-true model (MPU-6500 words -> CORDIC atan2 roll/pitch ->
steady-state Kalman filter with ``>>> 6`` gains -> 6-byte UART packets) and the packet decoder.
"""
