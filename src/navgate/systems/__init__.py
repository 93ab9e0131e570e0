"""The seed systems, one package each, with their faces side by side.

* :mod:`navgate.systems.ins_trn` - seed 000: the INS/TRN navigation of the Zynq-7020 design
  (navigation loop, the ``navgate fly`` run and its report);
* :mod:`navgate.systems.tinykalman` - seed 001: TinyKalman, integer bit-true model;
* :mod:`navgate.systems.gpsins` - seed 002: loosely coupled GPS/INS (RK4 INS, 9-state filter,
  optimal-filter bound, scenario);
* :mod:`navgate.systems.attitude` - seed 003: the Mahony-type attitude-solving circuit's float64
  and float32 models, and the attitude estimators behind ``navgate ahrs``;
* :mod:`navgate.systems.kf2x2` - seed 004: frame program, bit-true model, schedule, gateware.

Systems import the shared libraries (``nav``, ``trn``, ``numerics``, ``gateware``, ``devices``,
``hw``, ``sim``); no shared library imports a system (docs/architecture.md).

:data:`BLOCKS` lists the systems' gateware blocks for ``navgate build`` / ``navgate report``; it
is published to :mod:`navgate.hw.blocks` through the ``navgate.blocks`` entry point
(pyproject.toml). Factories are ``"module:attribute"`` strings, imported only when built.
"""

#: name -> ("module:attribute" of a zero-argument factory, one-line description)
BLOCKS: dict[str, tuple[str, str]] = {
    "kf2x2": ("navgate.systems.kf2x2.top:Kf2x2", "seed 004 2x2 adaptive Kalman filter"),
    "ins_engines": ("navgate.systems.ins_trn.engines:InsEngines",
                    "seed 000 INS engines: propagate + altitude/TRN updates, shared fp32 units"),
    "kalman_update_engine": ("navgate.systems.ins_trn.engines:KalmanUpdateEngine",
                             "seed 000 Kalman update engine (1-D altitude, 2-D TRN), fp32"),
    "ins_mechanization": ("navgate.systems.ins_trn.engines:InsMechanization",
                          "seed 000 IMU calibration + INS mechanization, fp32, one sample"),
    "covariance_propagator": ("navgate.systems.ins_trn.engines:CovariancePropagator",
                              "seed 000 Phi/Q generation + covariance propagation, fp32"),
}
