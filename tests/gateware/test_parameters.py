"""Rejected constructor parameters (navgate.gateware.parameters): a ValueError naming the
parameter, and no half-built component left behind for Amaranth to warn about."""

import gc
import warnings

import pytest
from amaranth.hdl import Fragment

from navgate.gateware.cordic import CordicAtan2, CordicAtan2Iterative, CordicSinCos
from navgate.gateware.fixed import FixedMul
from navgate.gateware.fp32.convert import Fp32FromFixed, Fp32FromInt, Fp32ToFixed, Fp32ToInt
from navgate.gateware.fp32.div import Fp32Div
from navgate.gateware.fp32.div_iter import Fp32DivIter
from navgate.gateware.fp32.sqrt import Fp32Sqrt
from navgate.gateware.fp32.sqrt_iter import Fp32SqrtIter
from navgate.gateware.goldschmidt import GoldschmidtDivider, GoldschmidtReciprocal
from navgate.gateware.yardstick import RegisteredMul

REJECTED = [
    (lambda: CordicAtan2(width=1), "width"),
    (lambda: CordicAtan2Iterative(iterations=0), "iterations"),
    (lambda: CordicAtan2(compensate=True, gain_frac_bits=0), "gain_frac_bits"),
    (lambda: CordicSinCos(width=3), "width"),
    (lambda: CordicSinCos(16, 16, 16, 17), "guard_bits"),
    (lambda: GoldschmidtDivider(width=40), "width"),
    (lambda: GoldschmidtReciprocal(seed="cubic"), "seed"),
    (lambda: FixedMul(width=20, frac=41), "frac"),
    (lambda: RegisteredMul(0, 8), "widths"),
    (lambda: Fp32FromFixed(width=1), "width"),
    (lambda: Fp32FromInt(65), "width"),
    (lambda: Fp32ToFixed(32, 999), "frac_bits"),
    (lambda: Fp32ToInt(width=1.5), "width"),
    (lambda: Fp32Div(0), "steps_per_stage"),
    (lambda: Fp32Sqrt(steps_per_stage=26), "steps_per_stage"),
    (lambda: Fp32DivIter(3), "steps_per_cycle"),
    (lambda: Fp32SqrtIter(steps_per_cycle=True), "steps_per_cycle"),
]


@pytest.mark.parametrize("make,name", REJECTED)
def test_rejected_parameters_raise_and_leave_no_unused_component(make, name):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(ValueError, match=name):
            make()
        gc.collect()
    assert not [w for w in caught if "never used" in str(w.message)]


def test_a_component_built_and_dropped_is_still_reported_unused():
    """The check runs before creation without switching Amaranth's lint off: an accepted
    component that is never elaborated still draws the warning, one that is does not."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        CordicAtan2(width=12)
        Fragment.get(Fp32Div(steps_per_stage=2), None)
        gc.collect()
    unused = [str(w.message) for w in caught if "never used" in str(w.message)]
    assert len(unused) == 1 and "CordicAtan2" in unused[0]


def test_stepped_units_report_their_latency_from_the_class():
    for unit in (Fp32Div, Fp32Sqrt):
        for steps in (1, 2, 3, 25):
            built = unit(steps_per_stage=steps)
            assert built.LATENCY == unit.latency_for(steps)
            Fragment.get(built, None)
    assert Fp32Div.latency_for(1) == Fp32Div.LATENCY and Fp32Sqrt.latency_for(1) == Fp32Sqrt.LATENCY
