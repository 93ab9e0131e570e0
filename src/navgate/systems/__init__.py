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
    "attitude_top": ("navgate.systems.attitude.top:AttitudeTop",
                     "seed 003 attitude-solving circuit (INS_top, shared float32 units)"),
    "attitude_acc": ("navgate.systems.attitude.top:attitude_acc",
                     "seed 003 INS_acc: accelerometer error (3.1.2), own units"),
    "attitude_mag": ("navgate.systems.attitude.top:attitude_mag",
                     "seed 003 INS_mag: magnetometer error (3.1.3), own units"),
    "attitude_gyro": ("navgate.systems.attitude.top:attitude_gyro",
                      "seed 003 INS_gyro: gyro PI correction (3.1.4), own units"),
    "attitude_quat": ("navgate.systems.attitude.top:attitude_quat",
                      "seed 003 INS_quat: quaternion update (3.1.5), own units"),
    "attitude_matx": ("navgate.systems.attitude.top:attitude_matx",
                      "seed 003 INS_matx: DCM update (3.1.6), own units"),
    "attitude_euler": ("navgate.systems.attitude.top:attitude_euler",
                       "seed 003 INS_euler: Euler angles (3.1.7), own units"),
    "attitude_atan": ("navgate.systems.attitude.units:AtanCircuit",
                      "seed 003 fix16 arctangent (3.1.8): float32->Q2.13->CORDIC->float32"),
}
