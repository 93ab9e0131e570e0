"""imu_calibration and baro_compensation gateware, bit for bit against their bit-true models
(navgate.nav.calibration.apply_calibration_fp32; navgate.devices.bmp390.compensate_fp32), in
the Amaranth simulator (directed + a few random vectors) and in Verilator (many vectors)."""

import numpy as np

from navgate.devices import bmp390 as B
from navgate.gateware.verify import f32_formatter, verify
from navgate.nav.calibration import ImuCalibration, apply_calibration_fp32, calibration_to_fp32
from navgate.systems.ins_trn.pl.sensors.baro_compensation import BaroCompensation
from navgate.systems.ins_trn.pl.sensors.imu_calibration import (
    CYCLES,
    IN_FIELDS,
    LATENCY,
    PARAMS,
    ImuCalibrationBlock,
    param_words,
)


def _cal(seed):
    rng = np.random.default_rng(seed)
    return ImuCalibration(
        gyro_bias=rng.normal(0, 0.01, 3), gyro_matrix=np.eye(3) + rng.normal(0, 0.01, (3, 3)),
        accel_bias=rng.normal(0, 0.2, 3), accel_matrix=np.eye(3) + rng.normal(0, 0.01, (3, 3)))


def _imu_model(cal):
    c = calibration_to_fp32(cal)

    def model(x):
        g = np.stack([x["gx"], x["gy"], x["gz"]], 1)
        a = np.stack([x["ax"], x["ay"], x["az"]], 1)
        G, A = apply_calibration_fp32(c, g, a)
        return {"gx": G[:, 0], "gy": G[:, 1], "gz": G[:, 2],
                "ax": A[:, 0], "ay": A[:, 1], "az": A[:, 2]}

    return model


def _imu_vectors(n, seed):
    rng = np.random.default_rng(seed)
    edges = np.array([-32768, 32767, 0, 1, -1, 12345, -256])
    out = {}
    for f in IN_FIELDS:
        out[f] = np.concatenate([rng.permutation(edges), rng.integers(-32768, 32768, n)])
    return out


FMT = {f: f32_formatter for f in IN_FIELDS}


def test_imu_calibration_amaranth():
    cal = _cal(1)
    res = verify(ImuCalibrationBlock(cal), _imu_model(cal), _imu_vectors(5, 2), seed=3,
                 valid_prob=0.7, ready_prob=0.6, idle_limit=5000, formatters=FMT)
    res.assert_ok()
    # 48 operations of (unit latency + 1) cycles, unload 6, output register 1
    assert res.latency == LATENCY == 343 and CYCLES == 350


def test_imu_calibration_parameter_writes():
    """Parameters written through par_* (the CAL_* registers) replace the initial ones."""
    from amaranth.sim import Simulator

    from navgate.numerics.fp32 import bits_to_f32

    cal = _cal(4)
    dut = ImuCalibrationBlock()  # identity calibration at reset
    words = param_words(cal)
    got = {}

    async def bench(ctx):
        for k, name in enumerate(PARAMS):
            ctx.set(dut.par_we, 1)
            ctx.set(dut.par_addr, k)
            ctx.set(dut.par_data, words[name])
            await ctx.tick()
        ctx.set(dut.par_we, 0)
        for f, v in zip(IN_FIELDS, (100, -200, 300, 800, -800, 400), strict=True):
            ctx.set(getattr(dut.i.payload, f), v)
        ctx.set(dut.i.valid, 1)
        await ctx.tick().until(dut.i.ready)
        ctx.set(dut.i.valid, 0)
        ctx.set(dut.o.ready, 1)
        await ctx.tick().until(dut.o.valid)
        for f in IN_FIELDS:
            got[f] = ctx.get(getattr(dut.o.payload, f))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    x = {f: np.array([v]) for f, v in zip(IN_FIELDS, (100, -200, 300, 800, -800, 400),
                                          strict=True)}
    exp = _imu_model(cal)(x)
    assert {f: int(exp[f][0]) for f in IN_FIELDS} == got
    assert abs(bits_to_f32(np.uint32(got["gx"])) - 100 * 0.00625 * np.pi / 180) < 0.05


def _baro_vectors(n, seed):
    rng = np.random.default_rng(seed)
    p = np.concatenate([[B.PRESSURE_RANGE_PA[0], B.PRESSURE_RANGE_PA[1], 101325.0],
                        rng.uniform(*B.PRESSURE_RANGE_PA, n)])
    t = np.concatenate([[B.TEMPERATURE_RANGE_C[0], B.TEMPERATURE_RANGE_C[1], 25.0],
                        rng.uniform(*B.TEMPERATURE_RANGE_C, n)])
    up, ut = B.encode(p, t)
    nvm = int.from_bytes(B.nvm_bytes(), "little")
    return {"up": up, "ut": ut, "nvm": np.array([nvm] * len(up), dtype=object)}


def _baro_model(x):
    p, t = B.compensate_fp32(x["up"], x["ut"])
    return {"p": p, "t": t}


def test_baro_compensation_amaranth():
    res = verify(BaroCompensation(), _baro_model, _baro_vectors(3, 5), seed=1,
                 idle_limit=5000, formatters={"p": f32_formatter, "t": f32_formatter})
    res.assert_ok()


def test_engines_verilator():
    cal = _cal(7)
    res = verify(ImuCalibrationBlock(cal), _imu_model(cal), _imu_vectors(300, 8), seed=9,
                 valid_prob=0.9, ready_prob=0.9, idle_limit=5000, backend="verilator",
                 formatters=FMT)
    res.assert_ok()
    res = verify(BaroCompensation(), _baro_model, _baro_vectors(200, 10), seed=11,
                 idle_limit=5000, backend="verilator",
                 formatters={"p": f32_formatter, "t": f32_formatter})
    res.assert_ok()
