"""Seed 004: the 2x2 adaptive fixed-point Kalman filter, all its faces (docs/seed004-kf2x2.md).

``model`` (the frame program, bit-true model, float64 reference and the series-RLC scenario),
``schedule`` (the frame program on shared units, C0-C33), ``units`` (multipliers,
adder/subtractors, the serial Goldschmidt reciprocal), ``modules`` (the eight computation
modules), ``top`` (:class:`~navgate.systems.kf2x2.top.Kf2x2` start/done top level,
``Kf2x2Stream`` for the verification harness), ``rtl_sim`` (gateware vs bit-true model runs).

Submodules are imported on demand; importing this package pulls in nothing.
"""
