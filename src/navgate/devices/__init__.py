"""Data-sheet facts of the sensor parts navgate talks to, in one place.

One module per part: register addresses, word and frame layouts, LSB sizes, ranges and
timing limits, with encoders/decoders and bus-level device models for testbenches. The
simulator (:mod:`navgate.sim.sensors`), the calibration (:mod:`navgate.nav.calibration`), the
gateware and the tests import these facts from here, so that there is no second copy.

This package is a shared library: it knows no seed system (docs/architecture.md).
"""
