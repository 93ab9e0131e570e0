"""The compiled attitude solve against the float32 bit-true model (MahonyCircuitFP32): every
output word, the invalid and saturation flags, on random series (several parameter sets) and
on series with bad samples (zero vectors, NaN, infinities, subnormals, huge values)."""

from dataclasses import replace

import numpy as np
import pytest

from navgate.numerics.fp32 import f32_to_bits, floats_to_bits, is_nan
from navgate.systems.attitude.compiled import CompiledSolve
from navgate.systems.attitude.mahony import SEED003
from navgate.systems.attitude.mahony_fp32 import MahonyCircuitFP32

LANES, STEPS = 48, 30


def _series(rng):
    """(LANES, STEPS, 3) float32 words for acc, mag, gyro: each lane an independent series."""
    acc = rng.normal(0, 2, (LANES, STEPS, 3)) + [0.0, 0.0, 9.8]
    mag = rng.normal(0, 30, (LANES, STEPS, 3)) + [20.0, 0.0, 40.0]
    gyro = rng.normal(0, 30, (LANES, STEPS, 3)) * rng.choice([0.1, 1, 10], (LANES, 1, 1))
    return [f32_to_bits(x.astype(np.float32)) for x in (acc, mag, gyro)]


def _model(params, acc, mag, gyro):
    c = MahonyCircuitFP32(params, batch=LANES)
    out = np.zeros((LANES, STEPS, 7), np.uint32)
    flags = np.zeros((LANES, STEPS, 2), bool)
    for k in range(STEPS):
        r = c.solve(*([x[:, k, j] for j in range(3)] for x in (acc, mag, gyro)))
        out[:, k] = np.column_stack(list(r.q) + [r.euler.pitch, r.euler.roll, r.euler.yaw])
        flags[:, k, 0] = r.invalid
        flags[:, k, 1] = r.euler.saturated
    return out, flags


def _compare(params, acc, mag, gyro):
    want, want_flags = _model(params, acc, mag, gyro)
    for lane in range(LANES):
        out, flags = CompiledSolve(params).run(acc[lane], mag[lane], gyro[lane])
        np.testing.assert_array_equal(out, want[lane], err_msg=f"lane {lane}")
        np.testing.assert_array_equal(flags, want_flags[lane], err_msg=f"lane {lane}")
    return want_flags


@pytest.mark.parametrize("params", [
    SEED003,
    replace(SEED003, kp=2.5, ki=0.3, dt=0.0100794, mag_sign=(1.0, 1.0, 1.0), accel_sign=-1.0),
    replace(SEED003, gyro_scale=0.5, dt=0.02),
], ids=["seed", "x-io", "gyro-scale"])
def test_compiled_equals_bittrue_model_on_random_series(params):
    flags = _compare(params, *_series(np.random.default_rng(7)))
    assert not flags.any()


def test_compiled_equals_bittrue_model_on_bad_samples():
    acc, mag, gyro = _series(np.random.default_rng(8))
    bad = {1: ("acc", 0x00000000), 2: ("mag", 0x7FC00000), 3: ("gyro", 0x7F800000),
           4: ("acc", 0xFF800000), 5: ("mag", 0x00000001), 6: ("gyro", 0x7F7FFFFF),
           7: ("acc", 0x80000000), 8: ("mag", 0x00000000)}
    arrays = {"acc": acc, "mag": mag, "gyro": gyro}
    for lane, (name, word) in bad.items():
        arrays[name][lane, 10, :] = word  # a whole vector bad at step 10
    arrays["mag"][5, 10, 0] = f32_to_bits(np.float32(25.0))  # subnormal y, z beside a normal x
    flags = _compare(SEED003, acc, mag, gyro)
    assert not flags[0].any() and not flags[:, :10].any()
    # zero / NaN / infinite vectors make the solve NaN from step 10 on and saturate the atan
    for lane in (1, 2, 3, 4, 8):
        assert flags[lane, 10:, 0].all() and flags[lane, 10:, 1].all(), lane
    assert not flags[5].any()  # subnormals flush to zero, the vector stays valid


SPECIAL = [0x00000000, 0x80000000, 0x3F800000, 0xBF800000, 0x3F800001, 0xBF800001, 0x7F800000,
           0xFF800000, 0x7FC00000, 0x00800000, 0x40800000, 0xC0800000, 0x407FFFFF, 0xC0800001,
           0x3A800000, 0xBA7FFFFF, 0x39800000, 0x42652EE1, 0xC3B40000, 0x3E99999A]


def test_every_kind_equals_the_programs_evaluator_on_special_values():
    """Each op kind of the solve program (program.EVAL, numerics.fp32 and atan16) on every
    pair of special values: signed zeros, +-1 and their neighbours, infinities, NaN, the
    smallest normal, the Q2.13 range edges (+-4), a value that rounds to half an LSB."""
    from navgate.systems.attitude import atan16, compiled
    from navgate.systems.attitude.program import EVAL

    a, b = (np.array(v, np.uint32) for v in zip(*[(x, y) for x in SPECIAL for y in SPECIAL],
                                                strict=True))
    vals = np.column_stack([compiled._value(a), compiled._value(b)])
    kinds = compiled._KINDS
    ops = np.array([[compiled._CODE[k], 2 + i, 0, 1] for i, k in enumerate(kinds)], np.int64)
    out = np.zeros((len(a), len(kinds)))
    flags = np.zeros((len(a), 2), np.bool_)
    compiled._run(np.zeros(2 + len(kinds)), ops, compiled._ATAN_TABLE, atan16.HALF_PI_Z,
                  np.array([0, 1]), vals, np.zeros((0, 2), np.int64),
                  np.arange(2, 2 + len(kinds)), np.zeros(0, np.int64), out, flags)
    got = floats_to_bits(out).reshape(out.shape)
    for i, k in enumerate(kinds):
        args = (a, b)[:1] if k in ("sqrt", "neg", "dbl", "clampneg") else (a, b)
        want = np.asarray(EVAL[k](*args), np.uint32)
        want = np.where(is_nan(want), np.uint32(0x7FC00000), want)  # canonical, as exported
        bad = np.flatnonzero(got[:, i] != want)
        assert bad.size == 0, (k, [(hex(a[j]), hex(b[j]), hex(got[j, i]), hex(want[j]))
                                   for j in bad[:4]])
    sat = np.asarray(atan16.atan_fp32(a, b)[2], bool)
    np.testing.assert_array_equal(flags[:, 1], sat)
    assert sat.sum() > 50 and (~sat).sum() > 50
