"""Hand-derived cases for the float32 divider (navgate.gateware.fp32.div)."""

import numpy as np
import pytest

from navgate.gateware.fp32 import Fp32Div
from navgate.gateware.verify import simulate
from navgate.gateware.verify_fp32 import DIV_DIRECTED
from navgate.numerics import fp32 as F

#: (a, [b,] expected, why): the shared hand-derived table
CASES = DIV_DIRECTED


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
