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
    "spi_master_imu": ("navgate.systems.ins_trn.sensors.spi_master_imu:SpiMasterImu",
                       "seed 000 ADIS16500 burst reader (SPI mode 3, checksum, FIFO, counters)"),
    "spi_master_baro": ("navgate.systems.ins_trn.sensors.spi_master_baro:SpiMasterBaro",
                        "seed 000 BMP390 reader (NVM once, pressure/temperature reads)"),
    "baro_compensation": ("navgate.systems.ins_trn.sensors.baro_compensation:BaroCompensation",
                          "seed 000 BMP390 compensation engine, float32 on shared fp32 cores"),
    "uart_rx_lidar": ("navgate.systems.ins_trn.sensors.uart_rx_lidar:UartRxLidar",
                      "seed 000 TF-Luna 115200 8N1 receiver and 9-byte frame parser"),
    "imu_calibration": ("navgate.systems.ins_trn.sensors.imu_calibration:ImuCalibrationBlock",
                        "seed 000 IMU calibration: int16 -> float32 SI, bias/scale/misalignment"),
    "sensor_subsystem": ("navgate.systems.ins_trn.sensors.sensor_subsystem:SensorSubsystem",
                         "seed 000 sensor subsystem: three interfaces, calibration, compensation"),
}
