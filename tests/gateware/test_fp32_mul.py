"""Hand-derived cases for the float32 multiplier (navgate.gateware.fp32.mul)."""

import numpy as np
import pytest

from navgate.gateware.fp32 import Fp32Mul
from navgate.gateware.verify import simulate
from navgate.numerics import fp32 as F

QNAN, PINF, NINF = 0x7FC00000, 0x7F800000, 0xFF800000

# (a, b, expected, why)
CASES = [
    (0x3FC00000, 0x3FC00000, 0x40100000, "1.5 * 1.5 = 2.25"),
    (0x3F800001, 0x3F800001, 0x3F800002, "(1+2^-23)^2 = 1+2^-22+2^-46 -> 1+2^-22"),
    (0x3F800800, 0x3F800800, 0x3F801000, "(1+2^-12)^2 = 1+2^-11+2^-24: tie, even"),
    (0x3F800800, 0x3F800801, 0x3F801002, "1+2^-11+2^-23+2^-24+2^-35: above tie, up"),
    (0x3FFFFFFF, 0x3FFFFFFF, 0x407FFFFE, "(2-2^-23)^2 = 4-2^-21+2^-46 -> 4-2^-21"),
    (0x7F7FFFFF, 0x40000000, PINF, "max * 2 overflows"),
    (0xFF7FFFFF, 0x40000000, NINF, "-max * 2 = -inf"),
    (0x7F7FFFFF, 0x3F800000, 0x7F7FFFFF, "max * 1"),
    (0x00800000, 0x3F000000, 0x00000000, "2^-126 * 0.5 = 2^-127 -> +0"),
    (0x00800000, 0x3F7FFFFF, 0x00000000, "2^-126 * (1-2^-24): exact 24-bit, < 2^-126 -> 0"),
    (0x00800001, 0x3F7FFFFF, 0x00800000, "2^-126(1+2^-24-2^-47) rounds to 2^-126"),
    (0x80800000, 0x3F000000, 0x80000000, "-2^-127 -> -0"),
    (0x1F800000, 0x1F800000, 0x00000000, "2^-64 * 2^-64 = 2^-128 -> +0"),
    (0x20000000, 0x20000000, 0x00800000, "2^-63 * 2^-63 = 2^-126"),
    (0x00000000, PINF, QNAN, "0 * inf"),
    (0x00000001, NINF, QNAN, "subnormal * inf: subnormal reads as 0"),
    (0x80000000, 0x40A00000, 0x80000000, "-0 * 5 = -0"),
    (0x00400000, 0x7F000000, 0x00000000, "subnormal * 2^127 = +0"),
    (PINF, 0xC0000000, NINF, "inf * -2"),
    (0x7F800001, 0x3F800000, QNAN, "sNaN * 1"),
    (0xFFC12345, 0x00000000, QNAN, "NaN * 0"),
]


@pytest.mark.parametrize("a,b,expected,why", CASES, ids=[c[3] for c in CASES])
def test_model_matches_hand_derived(a, b, expected, why):
    assert int(F.fp32_mul(a, b)) == expected, why


def test_gateware_matches_hand_derived():
    a, b, expected, why = (np.array(c) for c in zip(*CASES, strict=True))
    out, _ = simulate(Fp32Mul(), {"a": a, "b": b})
    bad = [(w, hex(int(g)), hex(int(e))) for w, g, e in zip(why, out["r"], expected, strict=True)
           if int(g) != int(e)]
    assert bad == []
