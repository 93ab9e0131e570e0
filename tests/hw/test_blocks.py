"""The block registry (navgate.hw.blocks)."""

from __future__ import annotations

from fractions import Fraction

import pytest
from amaranth.hdl import Fragment

from navgate.hw.blocks import REGISTRY, all_blocks, get_block

OWN = {"cordic_atan2", "cordic_atan2_iter", "cordic_sincos", "goldschmidt_div",
       "goldschmidt_recip", "fixed_mul", "fp32_div_iter", "fp32_sqrt_iter"}


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


def test_systems_publish_their_blocks_through_the_entry_point():
    from navgate.hw.blocks import published_registries
    from navgate.systems import BLOCKS

    registries = published_registries()
    assert registries["systems"] is BLOCKS
    assert "kf2x2" in BLOCKS and "kf2x2" not in REGISTRY


def test_a_block_registered_twice_is_an_error(monkeypatch):
    from navgate.hw import blocks as hw_blocks

    monkeypatch.setattr(hw_blocks, "published_registries",
                        lambda: {"other": {"fixed_mul": ("x:y", "a second fixed_mul")}})
    with pytest.raises(ValueError, match="'fixed_mul' is registered by both"):
        hw_blocks.all_blocks()


def test_unknown_block():
    with pytest.raises(KeyError, match="unknown block 'nope'"):
        get_block("nope")
