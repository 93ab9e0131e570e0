"""The seed systems, one package each, with their faces side by side.

* :mod:`navgate.systems.ins_trn` - seed 000: the INS/TRN navigation of the Zynq-7020 design
  (navigation loop, the ``navgate fly`` run and its report);
* :mod:`navgate.systems.tinykalman` - seed 001: TinyKalman, integer bit-true model, the chip's
  gateware (TinyTapeout top) and its pin-level test benches;
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

#: name -> ("module:attribute" of a zero-argument factory, one-line description).
#: Seed 001's angle block (``TinyKalmanCordic``) and data path (``TinyKalmanDatapath``) are not
#: listed: YoWASP Yosys 0.70's ``synth_xilinx`` aborts on them alone (an ABC ``&verify``
#: assertion), which would stop ``navgate report``; the chip that contains them synthesises,
#: and their CORDIC is the shared ``cordic_atan2_iter`` core (docs/seed001-tinykalman.md).
BLOCKS: dict[str, tuple[str, str]] = {
    "kf2x2": ("navgate.systems.kf2x2.top:Kf2x2", "seed 004 2x2 adaptive Kalman filter"),
    "ins_trn_regs": ("navgate.systems.ins_trn.pl.registers:register_bank",
                     "seed 000 AXI4-Lite register bank from its SystemRDL map (+ C header, docs)"),
    "altitude_profile_manager": (
        "navgate.systems.ins_trn.pl.profile_manager:AltitudeProfileManager",
        "seed 000 altitude profile FIFO (64 x 128 bit, one RAMB18) with AXI4 burst DMA to DDR"),
    "tinykalman_top": ("navgate.systems.tinykalman.top:TinyKalmanTop",
                       "seed 001 TinyKalman chip, TinyTapeout user module (10 MHz, 100 Hz loop)"),
    "tinykalman_serial_top": ("navgate.systems.tinykalman.top:TinyKalmanSerialTop",
                              "seed 001 TinyKalman chip, bit-serial CORDIC and filter "
                              "(one SG13G2 1x1 tile)"),
    "mpu6500_spi": ("navgate.systems.tinykalman.spi:Mpu6500Spi",
                    "seed 001 MPU-6500 SPI master: WHO_AM_I + 14-byte burst, mode 3, 1 MHz"),
    "kalman_steady": ("navgate.systems.tinykalman.datapath:KalmanSteady",
                      "seed 001 steady-state Kalman filter, >>> 6 gains, two axes"),
    "uart_tx": ("navgate.systems.tinykalman.uart:UartTx",
                "seed 001 8N1 UART transmitter (9596.9 baud at 10 MHz)"),
    "spi_master_imu": ("navgate.systems.ins_trn.pl.sensors.spi_master_imu:SpiMasterImu",
                       "seed 000 ADIS16500 burst reader (SPI mode 3, checksum, FIFO, counters)"),
    "spi_master_baro": ("navgate.systems.ins_trn.pl.sensors.spi_master_baro:SpiMasterBaro",
                        "seed 000 BMP390 reader (NVM once, pressure/temperature reads)"),
    "baro_compensation": ("navgate.systems.ins_trn.pl.sensors.baro_compensation:BaroCompensation",
                          "seed 000 BMP390 compensation engine, float32 on shared fp32 cores"),
    "uart_rx_lidar": ("navgate.systems.ins_trn.pl.sensors.uart_rx_lidar:UartRxLidar",
                      "seed 000 TF-Luna 115200 8N1 receiver and 9-byte frame parser"),
    "imu_calibration": ("navgate.systems.ins_trn.pl.sensors.imu_calibration:ImuCalibrationBlock",
                        "seed 000 IMU calibration: int16 -> float32 SI, bias/scale/misalignment"),
    "sensor_subsystem": ("navgate.systems.ins_trn.pl.sensors.sensor_subsystem:SensorSubsystem",
                         "seed 000 sensor subsystem: three interfaces, calibration, compensation"),
    "nav_output_formatter": ("navgate.systems.ins_trn.pl.output_formatter:NavOutputFormatter",
                             "seed 000 nav_output_formatter: state words -> POS/VEL/QUAT/Euler"),
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
    # Seed 000's whole PL (navgate.systems.ins_trn.pl.top, docs/seed000-top.md); with
    # --target zybo-z7-20 the board variant (MMCM clocking) plus XDC and filelist
    "ins_trn_top": ("navgate.systems.ins_trn.pl.top:InsTrnTop",
                    "seed 000 ins_trn_top: registers, sensors, sequencer, engines, formatter, "
                    "profile DMA, interrupts"),
    # Seed 000's PL engines (navgate.systems.ins_trn.pl.nav_engines): the banked scheduled float32
    # datapath (navgate.opflow, docs/seed000-engines.md)
    "ins_engines": ("navgate.systems.ins_trn.pl.nav_engines:InsEngines",
                    "seed 000 INS engines: propagate + altitude/TRN updates, shared fp32 units"),
    # the same on opflow's register machine (docs/opflow-register-machine.md)
    "ins_trn_top_compact": ("navgate.systems.ins_trn.pl.top:InsTrnTopCompact",
                            "seed 000 ins_trn_top with the register machine as its engines"),
    "ins_engines_compact": ("navgate.systems.ins_trn.pl.register_engine:ins_engines_compact",
                            "seed 000 engines on the register machine: one op per cycle, "
                            "fp32"),
    "kalman_update_engine": ("navgate.systems.ins_trn.pl.nav_engines:KalmanUpdateEngine",
                             "seed 000 Kalman update engine (1-D altitude, 2-D TRN), fp32"),
    "ins_mechanization": ("navgate.systems.ins_trn.pl.nav_engines:InsMechanization",
                          "seed 000 IMU calibration + INS mechanization, fp32, one sample"),
    "covariance_propagator": ("navgate.systems.ins_trn.pl.nav_engines:CovariancePropagator",
                              "seed 000 Phi/Q generation + covariance propagation, fp32"),
}
