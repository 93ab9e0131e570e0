"""Hand-derived cases for the float32 square root (navgate.gateware.fp32.sqrt)."""

import numpy as np
import pytest

from navgate.gateware.fp32 import Fp32Sqrt
from navgate.gateware.verify import simulate
from navgate.gateware.verify_fp32 import SQRT_DIRECTED
from navgate.numerics import fp32 as F

#: (a, [b,] expected, why): the shared hand-derived table
CASES = SQRT_DIRECTED


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
