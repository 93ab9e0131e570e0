"""Hand-derived cases for the float32 square root (navgate.gateware.fp32.sqrt)."""

import numpy as np
import pytest

from navgate.gateware.fp32 import Fp32Sqrt
from navgate.gateware.verify import simulate
from navgate.numerics import fp32 as F

QNAN, PINF, NINF = 0x7FC00000, 0x7F800000, 0xFF800000

# (a, expected, why)
CASES = [
    (0x40800000, 0x40000000, "sqrt(4) = 2"),
    (0x40000000, 0x3FB504F3, "sqrt(2) = 1.0110101000001001111001100110011...b -> 0x3FB504F3"),
    (0x3F800000, 0x3F800000, "sqrt(1) = 1"),
    (0x41100000, 0x40400000, "sqrt(9) = 3 (odd exponent path)"),
    (0x00800000, 0x20000000, "sqrt(2^-126) = 2^-63"),
    (0x7F7FFFFF, 0x5F7FFFFF, "sqrt(max) = 2^64 sqrt(1-2^-24) -> 2^64(1-2^-24)"),
    (0x3F7FFFFF, 0x3F7FFFFF, "sqrt(1-2^-24) = 1-2^-25-..: just below the tie -> 1-2^-24"),
    (0x00000000, 0x00000000, "sqrt(+0) = +0"),
    (0x80000000, 0x80000000, "sqrt(-0) = -0"),
    (0x00000001, 0x00000000, "sqrt(subnormal) = +0"),
    (0x80000001, 0x80000000, "sqrt(-subnormal) = sqrt(-0) = -0"),
    (0xBF800000, QNAN, "sqrt(-1)"),
    (PINF, PINF, "sqrt(inf)"),
    (NINF, QNAN, "sqrt(-inf)"),
    (0x7F800001, QNAN, "sqrt(sNaN)"),
]


@pytest.mark.parametrize("a,expected,why", CASES, ids=[c[2] for c in CASES])
def test_model_matches_hand_derived(a, expected, why):
    assert int(F.fp32_sqrt(a)) == expected, why


def test_gateware_matches_hand_derived():
    a, expected, why = (np.array(c) for c in zip(*CASES, strict=True))
    out, run = simulate(Fp32Sqrt(), {"a": a})
    bad = [(w, hex(int(g)), hex(int(e))) for w, g, e in zip(why, out["r"], expected, strict=True)
           if int(g) != int(e)]
    assert bad == []
    assert run.latency == Fp32Sqrt.LATENCY == 29
