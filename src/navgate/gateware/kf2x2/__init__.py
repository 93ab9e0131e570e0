"""Seed 004: the 2x2 adaptive fixed-point Kalman filter in gateware, 34 cycles a frame.

``schedule`` (the frame program on shared units, C0-C33), ``units`` (multipliers,
adder/subtractors, the serial Goldschmidt reciprocal), ``modules`` (the eight computation
modules), ``top`` (:class:`Kf2x2` start/done top level, :class:`Kf2x2Stream` for the
verification harness), ``sim`` (gateware vs bit-true model runs). The bit-true model and the
float64 reference are in :mod:`navgate.numerics.kf2x2`; docs/seed004-kf2x2.md is the guide.
"""

from navgate.gateware.kf2x2.top import Kf2x2, Kf2x2Stream, ModuleHarness

__all__ = ["Kf2x2", "Kf2x2Stream", "ModuleHarness"]
