"""Hand-derived cases for the float32 divider (navgate.gateware.fp32.div)."""

import numpy as np
import pytest

from navgate.gateware.fp32 import Fp32Div
from navgate.gateware.verify import simulate
from navgate.numerics import fp32 as F

QNAN, PINF, NINF = 0x7FC00000, 0x7F800000, 0xFF800000

# (a, b, expected, why)
CASES = [
    (0x3F800000, 0x40400000, 0x3EAAAAAB, "1/3 = 0.0101...b -> 0x3EAAAAAB (round up)"),
    (0x40000000, 0x40400000, 0x3F2AAAAB, "2/3"),
    (0x40C00000, 0x40400000, 0x40000000, "6/3 = 2 exactly"),
    (0x3F800000, 0x3F7FFFFF, 0x3F800001, "1/(1-2^-24) = 1+2^-24+2^-48+...: above tie"),
    (0x3F800000, 0x3F800001, 0x3F7FFFFE, "1/(1+2^-23) = 1-2^-23+2^-46: -> 1-2^-23"),
    (0x3F800000, 0x7F7FFFFF, 0x00000000, "1/max ~ 2^-128 -> +0"),
    (0x00800000, 0x3F800001, 0x00000000, "2^-126/(1+2^-23) rounds below 2^-126 -> 0"),
    (0x00800000, 0x3F7FFFFF, 0x00800001, "2^-126/(1-2^-24) = 2^-126(1+2^-24+..) -> +1 ulp"),
    (0x7F7FFFFF, 0x3F000000, PINF, "max/0.5 overflows"),
    (0x7F7FFFFF, 0xBF7FFFFF, 0xFF800000, "max/-(1-2^-24) = -max(1+2^-24..) -> -inf"),
    (0x3F800000, 0x00000000, PINF, "1/+0"),
    (0x3F800000, 0x80000000, NINF, "1/-0"),
    (0xBF800000, 0x00000001, NINF, "-1/subnormal: subnormal reads as +0"),
    (0x00000000, 0x00000000, QNAN, "0/0"),
    (0x00000001, 0x80000002, QNAN, "subnormal/subnormal = 0/0"),
    (PINF, NINF, QNAN, "inf/inf"),
    (PINF, 0x00000000, PINF, "inf/0"),
    (NINF, 0x40000000, NINF, "-inf/2"),
    (0x00000000, PINF, 0x00000000, "0/inf"),
    (0x3F800000, NINF, 0x80000000, "1/-inf = -0"),
    (0x80000000, 0x3F800000, 0x80000000, "-0/1 = -0"),
    (0x7FC00000, 0x00000000, QNAN, "NaN/0"),
]


@pytest.mark.parametrize("a,b,expected,why", CASES, ids=[c[3] for c in CASES])
def test_model_matches_hand_derived(a, b, expected, why):
    assert int(F.fp32_div(a, b)) == expected, why


def test_gateware_matches_hand_derived():
    a, b, expected, why = (np.array(c) for c in zip(*CASES, strict=True))
    out, run = simulate(Fp32Div(), {"a": a, "b": b})
    bad = [(w, hex(int(g)), hex(int(e))) for w, g, e in zip(why, out["r"], expected, strict=True)
           if int(g) != int(e)]
    assert bad == []
    assert run.latency == Fp32Div.LATENCY == 30
