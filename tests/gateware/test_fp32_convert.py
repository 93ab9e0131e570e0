"""Hand-derived cases for the float32 <-> integer / Q-format converters."""

import numpy as np
import pytest

from navgate.gateware.fp32 import Fp32FromFixed, Fp32FromInt, Fp32ToFixed, Fp32ToInt
from navgate.gateware.verify import simulate
from navgate.numerics import fp32 as F

I32_MAX, I32_MIN = (1 << 31) - 1, -(1 << 31)

# int32 -> float32: (x, expected, why)
FROM_INT = [
    (0, 0x00000000, "0 -> +0"),
    (-1, 0xBF800000, "-1"),
    (16777217, 0x4B800000, "2^24+1: tie, even is 2^24"),
    (16777219, 0x4B800002, "2^24+3: tie, even is 2^24+4"),
    (16777218, 0x4B800001, "2^24+2 exact"),
    (I32_MIN, 0xCF000000, "-2^31 exact"),
    (I32_MAX, 0x4F000000, "2^31-1 rounds to 2^31"),
]
# float32 -> int32: (a, value, flag, why)
TO_INT = [
    (0x40200000, 2, 0, "2.5 -> 2 (tie, even)"),
    (0x40600000, 4, 0, "3.5 -> 4 (tie, even)"),
    (0xC0200000, -2, 0, "-2.5 -> -2"),
    (0x3F000000, 0, 0, "0.5 -> 0"),
    (0x3FC00000, 2, 0, "1.5 -> 2"),
    (0x3F000001, 1, 0, "just above 0.5 -> 1"),
    (0x4EFFFFFF, 2147483520, 0, "largest float below 2^31"),
    (0x4F000000, I32_MAX, 1, "2^31 saturates"),
    (0xCF000000, I32_MIN, 0, "-2^31 fits"),
    (0xCF000001, I32_MIN, 1, "below -2^31 saturates"),
    (0x7F800000, I32_MAX, 1, "+inf saturates"),
    (0xFF800000, I32_MIN, 1, "-inf saturates"),
    (0x7FC00000, 0, 1, "NaN -> 0 with flag"),
    (0x80000001, 0, 0, "-subnormal -> 0"),
]
# Q16.16 (defaults of the fixed-point cores)
FROM_Q16 = [
    (98304, 0x3FC00000, "1.5"),
    (1, 0x37800000, "2^-16"),
    (I32_MIN, 0xC7000000, "-32768"),
    (-1, 0xB7800000, "-2^-16"),
]
TO_Q16 = [
    (0x3FC00000, 98304, 0, "1.5"),
    (0x37000000, 0, 0, "2^-17 = half an LSB: tie, even is 0"),
    (0x37C00000, 2, 0, "1.5*2^-16 = 1.5 LSB: tie, even is 2"),
    (0x38200000, 2, 0, "2.5*2^-16 = 2.5 LSB: tie, even is 2"),
    (0x47000000, I32_MAX, 1, "32768 saturates"),
    (0xC7000000, I32_MIN, 0, "-32768 fits"),
]


def _run(dut, fields):
    return simulate(dut, fields)


@pytest.mark.parametrize("x,expected,why", FROM_INT, ids=[c[2] for c in FROM_INT])
def test_from_int_model(x, expected, why):
    assert int(F.fp32_from_int(x)) == expected


@pytest.mark.parametrize("a,value,flag,why", TO_INT, ids=[c[3] for c in TO_INT])
def test_to_int_model(a, value, flag, why):
    v, f = F.fp32_to_int(a)
    assert (int(v), bool(f)) == (value, bool(flag))


def test_from_int_gateware():
    x, expected, why = zip(*FROM_INT, strict=True)
    out, run = _run(Fp32FromInt(), {"x": np.array(x, dtype=np.int64)})
    assert [hex(int(v)) for v in out["r"]] == [hex(e) for e in expected]
    assert run.latency == Fp32FromInt.LATENCY


def test_to_int_gateware():
    a, value, flag, why = zip(*TO_INT, strict=True)
    out, run = _run(Fp32ToInt(), {"a": np.array(a, dtype=np.uint32)})
    assert list(out["r"]) == list(value)
    assert list(out["overflow"]) == list(flag)
    assert run.latency == Fp32ToInt.LATENCY


def test_q16_16_both_directions():
    x, expected, _ = zip(*FROM_Q16, strict=True)
    assert [int(F.fp32_from_fixed(v, 16, 32)) for v in x] == list(expected)
    out, _ = _run(Fp32FromFixed(), {"x": np.array(x, dtype=np.int64)})
    assert [int(v) for v in out["r"]] == list(expected)
    a, value, flag, _ = zip(*TO_Q16, strict=True)
    assert [int(F.fp32_to_fixed(v, 16, 32)[0]) for v in a] == list(value)
    out, _ = _run(Fp32ToFixed(), {"a": np.array(a, dtype=np.uint32)})
    assert list(out["r"]) == list(value) and list(out["overflow"]) == list(flag)


def test_rejects_bad_parameters():
    with pytest.raises(ValueError, match="width"):
        Fp32ToFixed(width=1)
    with pytest.raises(ValueError, match="width"):
        Fp32FromFixed(width=65)
    with pytest.raises(ValueError, match="frac_bits"):
        Fp32FromFixed(frac_bits=1.5)
