"""navgate: GPS-denied navigation from reference model to verified gateware.

Subpackages (see docs/architecture.md):

- ``navgate.systems``: one package per seed system, its faces side by side: ``ins_trn``
  (seed 000), ``tinykalman`` (001), ``gpsins`` (002), ``attitude`` (003), ``kf2x2`` (004).

Shared libraries, which import no system:

- ``navgate.nav``: frames, Earth model, strapdown INS, error-state Kalman filters
  (float64 reference).
- ``navgate.trn``: DEM access, altitude profile buffer, terrain correlation.
- ``navgate.numerics``: bit-true float32 and fixed-point arithmetic, CORDIC, Goldschmidt.
- ``navgate.gateware``: Amaranth 0.5 arithmetic cores and the verification harness.
- ``navgate.devices``: data-sheet facts of the sensor parts.
- ``navgate.hw``: Verilog emission, synthesis and resource reports.
- ``navgate.sim``: trajectories, sensor error models, the flight scenario, IMU logs.

On top: ``navgate.cli``, the ``navgate`` command.
"""

__version__ = "0.1.0"
