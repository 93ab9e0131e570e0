"""The block registry (navgate.hw.blocks)."""

from __future__ import annotations

from fractions import Fraction

import pytest
from amaranth.hdl import Fragment

from navgate.hw.blocks import REGISTRY, all_blocks, get_block

OWN = {"cordic_atan2", "cordic_atan2_iter", "cordic_sincos", "goldschmidt_div",
       "goldschmidt_recip", "fixed_mul"}


def test_registry_names_and_fp32_merge():
    blocks = all_blocks()
    assert OWN <= set(blocks) and OWN <= set(REGISTRY)
    assert {"fp32_add", "fp32_mul", "fp32_div", "fp32_sqrt", "kf2x2"} <= set(blocks)
    assert list(blocks) == sorted(blocks)
    assert all(block.description and "\n" not in block.description
               for block in blocks.values())


@pytest.mark.parametrize("name", sorted(OWN | {"fp32_add", "fp32_mul"}))
def test_factories_build_documented_components(name):
    component = get_block(name).factory()
    Fragment.get(component, None)  # elaborates without error
    assert int(component.LATENCY) >= 1
    throughput = Fraction(component.THROUGHPUT).limit_denominator(1 << 16)
    assert 0 < throughput <= 1
    assert hasattr(component, "i") and hasattr(component, "o")


def test_unknown_block():
    with pytest.raises(KeyError, match="unknown block 'nope'"):
        get_block("nope")
