"""Hand-derived cases for the float32 comparator (navgate.gateware.fp32.compare)."""

import numpy as np

from navgate.gateware.fp32 import Fp32Compare
from navgate.gateware.verify import simulate
from navgate.numerics import fp32 as F

# (a, b, outcome, why) with outcome one of lt / eq / gt / unordered
CASES = [
    (0x00000000, 0x80000000, "eq", "+0 == -0"),
    (0x00000001, 0x00000000, "eq", "subnormal == 0 (input flush)"),
    (0x807FFFFF, 0x00400000, "eq", "-subnormal == +subnormal"),
    (0xBF800000, 0x3F800000, "lt", "-1 < 1"),
    (0xC0000000, 0xBF800000, "lt", "-2 < -1"),
    (0x3F800000, 0x3F800001, "lt", "1 < 1 + ulp"),
    (0xBF800001, 0xBF800000, "lt", "-(1+ulp) < -1"),
    (0x7F800000, 0x7F7FFFFF, "gt", "inf > max"),
    (0xFF800000, 0xFF7FFFFF, "lt", "-inf < -max"),
    (0x00800000, 0x00000001, "gt", "min normal > subnormal(=0)"),
    (0x80800000, 0x00000000, "lt", "-min normal < 0"),
    (0x7FC00000, 0x7FC00000, "unordered", "NaN vs NaN"),
    (0x3F800000, 0xFF800001, "unordered", "1 vs NaN"),
    (0x7F800000, 0x7F800000, "eq", "inf == inf"),
]
KEYS = {"lt": "lt", "eq": "equal", "gt": "gt", "unordered": "unordered"}


def test_model_matches_hand_derived():
    for a, b, outcome, why in CASES:
        r = F.fp32_compare(a, b)
        assert [k for k, v in r.items() if v] == [outcome], why


def test_gateware_matches_hand_derived():
    a, b, outcome, why = (np.array(c) for c in zip(*CASES, strict=True))
    out, run = simulate(Fp32Compare(), {"a": a, "b": b})
    for j, (o, w) in enumerate(zip(outcome, why, strict=True)):
        got = [k for k, field in KEYS.items() if out[field][j]]
        assert got == [o], w
    assert run.latency == Fp32Compare.LATENCY == 2
