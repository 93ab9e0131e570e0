"""navgate: GPS-denied navigation from reference model to verified gateware.

Subpackages (see docs/architecture.md):

- ``navgate.nav``: frames, Earth model, strapdown INS, error-state Kalman filters
  (float64 reference).
- ``navgate.trn``: DEM access, altitude profile buffer, terrain correlation.
- ``navgate.sim``: trajectories, sensor models, scenarios.
- ``navgate.numerics``: bit-true float32 and fixed-point arithmetic, CORDIC, Goldschmidt.
- ``navgate.gateware``: Amaranth 0.5 components.
- ``navgate.hw``: Verilog emission, synthesis and resource reports.
- ``navgate.attitude``: attitude filters of seeds 001 and 003 (Mahony, TinyKalman).
- ``navgate.gpsins``: the seed-002 loosely coupled GPS/INS.
- ``navgate.cli``: the ``navgate`` command.
"""

__version__ = "0.1.0"
