"""sensor_subsystem end to end in the Amaranth simulator: the three device models on the pins,
float32 outputs compared bit for bit with the bit-true models (apply_calibration_fp32,
bmp390.compensate_fp32) and the frames with the TF-Luna source."""

import numpy as np
from amaranth.sim import Simulator

from navgate.devices import adis16500 as A
from navgate.devices import bmp390 as B
from navgate.devices import tfluna as L
from navgate.devices.bench import CycleCounter, spi_slave_testbench, uart_source_testbench
from navgate.nav.calibration import ImuCalibration, apply_calibration_fp32, calibration_to_fp32
from navgate.systems.ins_trn.pl.sensors.imu_calibration import IN_FIELDS
from navgate.systems.ins_trn.pl.sensors.sensor_subsystem import SensorSubsystem

CLK_HZ = L.BAUD * 16 * 3  # 5.5296 MHz: UART divider 2 exact, SPI half period 3 -> 0.92 MHz


def test_sensor_subsystem_end_to_end():
    rng = np.random.default_rng(4)
    cal = ImuCalibration(gyro_bias=rng.normal(0, 0.01, 3),
                         gyro_matrix=np.eye(3) + rng.normal(0, 0.01, (3, 3)),
                         accel_bias=rng.normal(0, 0.2, 3),
                         accel_matrix=np.eye(3) + rng.normal(0, 0.01, (3, 3)))
    imu_st = A.ImuStream(rng.integers(-3000, 3000, (16, 3)), rng.integers(-9000, 9000, (16, 3)),
                         faults={1: "bad_checksum"})
    baro_st = B.BaroStream.from_physical(rng.uniform(*B.PRESSURE_RANGE_PA, 16),
                                         rng.uniform(*B.TEMPERATURE_RANGE_C, 16))
    frames = L.encode_frames([1.5, 2.5], [800, 900], 25.0)
    tr, end = L.stream_transitions(L.LidarStream(frames))
    imu_m, baro_m = A.Adis16500Model(imu_st), B.Bmp390Model(baro_st)

    dut = SensorSubsystem(tick_cycles=1, cal=cal)
    top = CycleCounter(dut)
    sim = Simulator(top)
    sim.add_clock(1 / CLK_HZ)
    sim.add_testbench(spi_slave_testbench(imu_m, dut.imu_cs_n, dut.imu_sclk, dut.imu_mosi,
                                          dut.imu_miso, top.cycles, CLK_HZ), background=True)
    sim.add_testbench(spi_slave_testbench(baro_m, dut.baro_cs_n, dut.baro_sclk, dut.baro_mosi,
                                          dut.baro_miso, top.cycles, CLK_HZ), background=True)
    sim.add_testbench(uart_source_testbench(tr, dut.lidar_rx), background=True)
    got = {"imu": [], "baro": [], "lidar": []}
    counters = {}

    def collector(port, key, names):
        async def collect(ctx):
            async for (_valid,) in ctx.posedge(port.valid):
                got[key].append({n: ctx.get(getattr(port.payload, n)) for n in names})
        return collect

    sim.add_testbench(collector(dut.imu, "imu", list(IN_FIELDS) + ["cntr"]), background=True)
    sim.add_testbench(collector(dut.baro, "baro", ["p", "t"]), background=True)
    sim.add_testbench(collector(dut.lidar, "lidar", ["dist", "strength", "reliable"]),
                      background=True)

    async def main(ctx):
        ctx.set(dut.imu_cfg, 0x100 | 2)
        ctx.set(dut.baro_cfg, 0x100 | 2)
        ctx.set(dut.lidar_cfg, 0x100 | 2)
        ctx.set(dut.update_rate, 1300)
        ctx.set(dut.baro_rate, 1500)
        for s in (dut.imu, dut.baro, dut.lidar):
            ctx.set(s.ready, 1)
        await ctx.tick().repeat(int(end * CLK_HZ) + 600)
        for n in ("imu_samples", "imu_errors", "baro_samples", "baro_errors", "lidar_frames"):
            counters[n] = ctx.get(getattr(dut, n))

    sim.add_testbench(main)
    sim.run()

    served = imu_m.served
    good = [k for k in served if k != 1]
    assert len(good) >= 5 and counters["imu_errors"] == 1
    g, a = apply_calibration_fp32(calibration_to_fp32(cal), imu_st.gyro[good],
                                  imu_st.accel[good])
    exp = [dict(zip(IN_FIELDS, [int(x) for x in np.concatenate([g[i], a[i]])], strict=True))
           | {"cntr": k + 1} for i, k in enumerate(good)]
    assert got["imu"] == exp[:len(got["imu"])] and len(got["imu"]) >= len(exp) - 1
    p, t = B.compensate_fp32(baro_st.uncomp_press, baro_st.uncomp_temp)
    assert len(got["baro"]) >= 2 and counters["baro_errors"] == 0
    assert got["baro"] == [{"p": int(p[k]), "t": int(t[k])} for k in range(len(got["baro"]))]
    assert got["lidar"] == [{"dist": 150, "strength": 800, "reliable": 1},
                            {"dist": 250, "strength": 900, "reliable": 1}]
    assert imu_m.violations == [] and baro_m.violations == []
