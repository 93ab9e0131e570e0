"""Seed 000 ``sensor_subsystem``: the three sensor interfaces with the IMU calibration and the
BMP390 compensation engine (seed "Module Hierarchy").

    ADIS16500 pins -> spi_master_imu -> (16-deep FIFO) -> imu_calibration -> ``imu``
    BMP390 pins    -> spi_master_baro -> baro_compensation -> ``baro``
    TF-Luna RX     -> uart_rx_lidar -> ``lidar``

One clock domain (``sync``, the seed's 100 MHz clk_sys). The clock domains meet at the pins:
MISO (two SPI buses) and UART RX are asynchronous to ``sync`` and each passes a two-flip-flop
synchroniser inside its interface; SCLK, MOSI and CS_N are registered outputs. The 200 MHz
clk_dsp domain of the seed (navigation pipelines) is not part of this block: the ``imu``,
``baro`` and ``lidar`` streams are where a clock-domain crossing (an asynchronous FIFO) would
go if the consumer runs there.

Options (navgate extensions the FPGA top needs; the seed has only the timers): ``imu_dr``
is the ADIS16500's data-ready pin and ``imu_cfg`` bit 9 (IMU_CFG.dr_sync) makes
spi_master_imu burst on its rising
edge instead of the UPDATE_RATE timer (:class:`~.spi_master_imu.SpiMasterImu`). Likewise
``baro_int`` is the BMP390's INT pin (data ready) and ``baro_cfg`` bit 9 (BARO_CFG.int_sync)
makes spi_master_baro read a sample on its rising edge instead of the BARO_RATE timer
(:class:`~.spi_master_baro.SpiMasterBaro`).
``calibrate=False`` leaves out the calibration block (and its ``cal_*`` ports): the ``imu``
stream then carries the raw words straight from the IMU FIFO, each gyro/accel field the int16
word sign-extended to 32 bits (two's complement), with ``cntr`` and ``diag`` as before; the top
runs the calibration on shared float32 units instead.

float32 units: the calibration and the compensation each own one engine (one adder, one
multiplier, one int->float converter): 2 + 2 + 2 = 6 float32 units. Both engines are idle
almost all the time (400 Hz x 398 cycles and 25 Hz x 473 cycles of 100 MHz), so one engine
could serve both; kept separate here so that each block is verified on its own.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth.hdl import Cat, Module, Signal, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ..shared_units import forward_units, unit_members
from .baro_compensation import OUT_LAYOUT as BARO_LAYOUT
from .baro_compensation import BaroCompensation
from .imu_calibration import IN_FIELDS, ImuCalibrationBlock
from .imu_calibration import LATENCY as CAL_LATENCY
from .spi_master_baro import SpiMasterBaro
from .spi_master_imu import BURST_LATENCY, DEFAULT_RATE, SpiMasterImu
from .uart_rx_lidar import FRAME_LAYOUT, UartRxLidar

IMU_LAYOUT = data.StructLayout({**{f: unsigned(32) for f in IN_FIELDS},
                                "cntr": unsigned(16), "diag": unsigned(16)})
FP32_UNITS = {"add": 2, "mul": 2, "from_int": 2}


class SensorSubsystem(wiring.Component):
    """Seed 000 sensor_subsystem: IMU/baro/lidar interfaces, calibration, compensation."""

    def __init__(self, tick_cycles: int = 100, cal=None, calibrate: bool = True,
                 lidar_timeout_bits: int = 2304, shared_baro_units: bool = False):
        self.tick_cycles = tick_cycles
        #: True: baro_compensation's adder and multiplier are outside (ports ``baro_add_i``
        #: ... of :mod:`navgate.systems.ins_trn.pl.shared_units`, ``baro_grant``, ``baro_busy``)
        self.shared_baro_units = shared_baro_units
        self.cal = cal
        self.calibrate = calibrate
        #: the ranger's silence timeout in bit times (2304: 20 ms at 115200 baud, for the
        #: TF-Luna's 100 Hz frames; a 10 Hz ranger needs more)
        self.lidar_timeout_bits = lidar_timeout_bits
        #: IMU path: CS_N falling to the calibrated sample (burst + FIFO + calibration program);
        #: without calibration, CS_N falling to the raw sample at the FIFO output
        self.LATENCY = (BURST_LATENCY + 1 + len(IN_FIELDS) + CAL_LATENCY if calibrate
                        else BURST_LATENCY)
        cal_ports = ({"cal_we": In(1), "cal_addr": In(5), "cal_data": In(32),
                      "cal_ready": Out(1)} if calibrate else {})
        #: IMU samples per cycle (the fastest stream; baro 25 Hz, lidar 100 Hz)
        self.THROUGHPUT = Fraction(1, DEFAULT_RATE * tick_cycles)
        super().__init__({
            "imu_sclk": Out(1, init=1), "imu_mosi": Out(1), "imu_miso": In(1, init=1),
            "imu_cs_n": Out(1, init=1), "imu_dr": In(1),
            "baro_sclk": Out(1, init=1), "baro_mosi": Out(1), "baro_miso": In(1, init=1),
            "baro_cs_n": Out(1, init=1), "baro_int": In(1),
            "lidar_rx": In(1, init=1),
            "imu_cfg": In(10, init=0x100 | 49), "baro_cfg": In(10, init=0x100 | 5),
            "lidar_cfg": In(9, init=0x100 | 53), "update_rate": In(16, init=2500),
            "baro_rate": In(16, init=40000),
            **cal_ports,
            "imu": Out(stream.Signature(IMU_LAYOUT)),
            "baro": Out(stream.Signature(BARO_LAYOUT)),
            "lidar": Out(stream.Signature(FRAME_LAYOUT)),
            "imu_samples": Out(32), "imu_errors": Out(32), "baro_samples": Out(32),
            "baro_errors": Out(32), "lidar_frames": Out(16), "lidar_errors": Out(16),
            "sensor_error": Out(3),
            **({"baro_grant": In(1), "baro_busy": Out(1), **unit_members("baro_")}
               if shared_baro_units else {}),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.imu_if = imu = SpiMasterImu(self.tick_cycles)
        m.submodules.baro_if = baro = SpiMasterBaro(self.tick_cycles)
        m.submodules.baro_comp = comp = BaroCompensation(shared_units=self.shared_baro_units)
        if self.shared_baro_units:
            m.d.comb += [comp.grant.eq(self.baro_grant), self.baro_busy.eq(comp.busy)]
            forward_units(m, comp, self, "baro_")
        m.submodules.lidar_if = lidar = UartRxLidar(timeout_bits=self.lidar_timeout_bits)

        m.d.comb += [
            self.imu_sclk.eq(imu.sclk), self.imu_mosi.eq(imu.mosi), self.imu_cs_n.eq(imu.cs_n),
            imu.miso.eq(self.imu_miso), imu.cfg_spi_div.eq(self.imu_cfg[:8]),
            imu.cfg_enable.eq(self.imu_cfg[8]), imu.cfg_rate.eq(self.update_rate),
            imu.dr.eq(self.imu_dr), imu.cfg_dr_sync.eq(self.imu_cfg[9]),
            self.baro_sclk.eq(baro.sclk), self.baro_mosi.eq(baro.mosi),
            self.baro_cs_n.eq(baro.cs_n), baro.miso.eq(self.baro_miso),
            baro.cfg_spi_div.eq(self.baro_cfg[:8]), baro.cfg_enable.eq(self.baro_cfg[8]),
            baro.cfg_rate.eq(self.baro_rate), baro.int_pin.eq(self.baro_int),
            baro.cfg_int_sync.eq(self.baro_cfg[9]),
            lidar.rx.eq(self.lidar_rx), lidar.cfg_div.eq(self.lidar_cfg[:8]),
            lidar.cfg_enable.eq(self.lidar_cfg[8]),
            self.imu_samples.eq(imu.sample_count), self.imu_errors.eq(imu.error_count),
            self.baro_samples.eq(baro.sample_count), self.baro_errors.eq(baro.error_count),
            self.lidar_frames.eq(lidar.frame_count),
            self.lidar_errors.eq(lidar.checksum_errors + lidar.framing_errors),
            self.sensor_error.eq(Cat(imu.sensor_error, baro.sensor_error,
                                      lidar.sensor_error | lidar.timed_out)),
        ]
        if not self.calibrate:
            # raw words: int16 -> 32 bits, sign-extended (Amaranth extends a signed value)
            for f in IN_FIELDS:
                m.d.comb += getattr(self.imu.payload, f).eq(getattr(imu.o.payload, f))
            m.d.comb += [self.imu.payload.cntr.eq(imu.o.payload.cntr),
                         self.imu.payload.diag.eq(imu.o.payload.diag),
                         self.imu.valid.eq(imu.o.valid), imu.o.ready.eq(self.imu.ready)]
        else:
            self._calibration(m, imu)
        wiring.connect(m, baro.o, comp.i)
        wiring.connect(m, comp.o, wiring.flipped(self.baro))
        wiring.connect(m, lidar.o, wiring.flipped(self.lidar))
        return m

    def _calibration(self, m, imu):
        m.submodules.imu_cal = cal = ImuCalibrationBlock(self.cal)
        m.d.comb += [cal.par_we.eq(self.cal_we), cal.par_addr.eq(self.cal_addr),
                     cal.par_data.eq(self.cal_data), self.cal_ready.eq(cal.par_ready)]
        # IMU: raw sample -> calibration; the counter and status ride along (one in flight)
        cntr = Signal(16)
        diag = Signal(16)
        for f in IN_FIELDS:
            m.d.comb += getattr(cal.i.payload, f).eq(getattr(imu.o.payload, f))
        m.d.comb += [cal.i.valid.eq(imu.o.valid), imu.o.ready.eq(cal.i.ready)]
        with m.If(imu.o.valid & imu.o.ready):
            m.d.sync += [cntr.eq(imu.o.payload.cntr), diag.eq(imu.o.payload.diag)]
        for f in IN_FIELDS:
            m.d.comb += getattr(self.imu.payload, f).eq(getattr(cal.o.payload, f))
        m.d.comb += [self.imu.payload.cntr.eq(cntr), self.imu.payload.diag.eq(diag),
                     self.imu.valid.eq(cal.o.valid), cal.o.ready.eq(self.imu.ready)]

