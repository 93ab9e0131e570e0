"""Hand-derived cases for the float32 adder (navgate.gateware.fp32.add).

Expected patterns are worked out by hand from the format (comment per row), so
they check the bit-true model and the gateware independently of each other.
"""

import numpy as np
import pytest

from navgate.gateware.fp32 import Fp32Add
from navgate.gateware.verify import simulate
from navgate.numerics import fp32 as F

QNAN, PINF, NINF = 0x7FC00000, 0x7F800000, 0xFF800000

# (a, b, sub, expected, why)
CASES = [
    (0x3F800000, 0x3F800000, 0, 0x40000000, "1 + 1 = 2"),
    (0x3F800000, 0x33800000, 0, 0x3F800000, "1 + 2^-24: tie, even is 1"),
    (0x3F800001, 0x33800000, 0, 0x3F800002, "(1+2^-23) + 2^-24: tie, even is 1+2^-22"),
    (0x3F800000, 0x33800001, 0, 0x3F800001, "just above the tie rounds up"),
    (0x3F800000, 0x33000000, 1, 0x3F800000, "1 - 2^-25: tie between 1-2^-24 and 1, even is 1"),
    (0x3F800000, 0x0D800000, 0, 0x3F800000, "1 + 2^-100: sticky only"),
    (0x3F800000, 0x0D800000, 1, 0x3F800000, "1 - 2^-100 rounds back to 1"),
    (0x3F800001, 0x3F800000, 1, 0x34000000, "cancellation: (1+2^-23) - 1 = 2^-23"),
    (0x40490FDB, 0x40490FDB, 1, 0x00000000, "x - x = +0"),
    (0xC0490FDB, 0x40490FDB, 0, 0x00000000, "(-x) + x = +0"),
    (0x7F7FFFFF, 0x7F7FFFFF, 0, PINF, "max + max overflows"),
    (0x7F7FFFFF, 0x73000000, 0, PINF, "max + half ulp: tie, rounds to even 2^128 -> inf"),
    (0x7F7FFFFF, 0x72FFFFFF, 0, 0x7F7FFFFF, "max + just under half ulp stays max"),
    (0xFF7FFFFF, 0x7F7FFFFF, 1, NINF, "-max - max = -inf"),
    (0x00800000, 0x00800001, 1, 0x80000000, "2^-126 - (2^-126+2^-149) = -2^-149 -> -0"),
    (0x00800001, 0x00800000, 1, 0x00000000, "+2^-149 flushes to +0"),
    (0x01000000, 0x00800000, 1, 0x00800000, "2^-125 - 2^-126 = 2^-126 exactly"),
    (0x00C00000, 0x00800000, 1, 0x00000000, "1.5*2^-126 - 2^-126 = 2^-127 -> +0"),
    (0x80000000, 0x80000000, 0, 0x80000000, "(-0) + (-0) = -0"),
    (0x00000000, 0x80000000, 0, 0x00000000, "(+0) + (-0) = +0"),
    (0x80000000, 0x00000000, 1, 0x80000000, "(-0) - (+0) = -0"),
    (0x00000001, 0x00000000, 0, 0x00000000, "subnormal + 0 = +0 (input flush)"),
    (0x80000001, 0x80000000, 0, 0x80000000, "-subnormal + -0 = -0"),
    (0x007FFFFF, 0x3F800000, 0, 0x3F800000, "subnormal + 1 = 1 exactly"),
    (PINF, NINF, 0, QNAN, "inf - inf"),
    (PINF, PINF, 1, QNAN, "inf - inf via sub"),
    (PINF, PINF, 0, PINF, "inf + inf"),
    (NINF, 0x3F800000, 0, NINF, "-inf + 1"),
    (0x3F800000, NINF, 1, PINF, "1 - (-inf)"),
    (PINF, 0x7F800001, 0, QNAN, "inf + sNaN"),
    (0xFFFFFFFF, 0x3F800000, 0, QNAN, "NaN payload and sign are not propagated"),
]


@pytest.mark.parametrize("a,b,sub,expected,why", CASES, ids=[c[4] for c in CASES])
def test_model_matches_hand_derived(a, b, sub, expected, why):
    op = F.fp32_sub if sub else F.fp32_add
    assert int(op(a, b)) == expected, why


def test_gateware_matches_hand_derived():
    a, b, sub, expected, why = (np.array(c) for c in zip(*CASES, strict=True))
    out, _ = simulate(Fp32Add(), {"a": a, "b": b, "sub": sub})
    bad = [(w, hex(int(g)), hex(int(e))) for w, g, e in zip(why, out["r"], expected, strict=True)
           if int(g) != int(e)]
    assert bad == []
