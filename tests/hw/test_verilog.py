"""Verilog emission and block descriptions (navgate.hw.verilog)."""

from __future__ import annotations

import re

import pytest

from navgate.gateware.cordic import CordicAtan2Iterative
from navgate.gateware.fixed import FixedMul
from navgate.hw.verilog import describe_block, emit_verilog, verilog_ports


def test_emission_is_deterministic_and_named_after_the_block():
    first = emit_verilog(FixedMul(), "fixed_mul")
    second = emit_verilog(FixedMul(), "fixed_mul")
    assert first == second
    tops = re.findall(r"^module (\S+)\(", first, re.MULTILINE)
    assert tops == ["fixed_mul"]
    assert ".py:" not in first  # emit_src=False: no source locations


def test_deterministic_across_parameters_and_instances():
    a = emit_verilog(CordicAtan2Iterative(width=10, iterations=8), "c")
    b = emit_verilog(CordicAtan2Iterative(width=10, iterations=8), "c")
    c = emit_verilog(CordicAtan2Iterative(width=10, iterations=9), "c")
    assert a == b != c


def test_bad_module_name_rejected():
    dut = FixedMul()
    with pytest.raises(ValueError):
        emit_verilog(dut, "not a name")
    emit_verilog(dut, "ok")  # the component is still usable


def test_description_of_fixed_mul():
    dut = FixedMul(width=12, frac=6)
    text = emit_verilog(dut, "fixed_mul")
    desc = describe_block(dut, "fixed_mul", "a multiplier", text)
    assert desc["top_module"] == "fixed_mul"
    assert desc["latency_cycles"] == 3
    assert desc["throughput"] == "1" and desc["throughput_per_cycle"] == 1.0
    assert desc["initiation_interval_cycles"] == 1
    assert desc["parameters"] == {"width": 12, "frac": 6}
    ports = {p["name"]: p for p in desc["ports"]}
    assert set(ports) == {"clk", "rst", "i__valid", "i__ready", "i__payload",
                          "o__valid", "o__ready", "o__payload"}
    assert [p["name"] for p in desc["ports"][:2]] == ["clk", "rst"]
    assert ports["i__payload"]["direction"] == "input" and ports["i__payload"]["width"] == 24
    assert ports["i__payload"]["fields"]["b"] == {"offset": 12, "width": 12, "signed": True}
    assert ports["i__ready"]["direction"] == "output"
    # full (24) + trunc (12) + sat (12) + overflow (1)
    assert ports["o__payload"]["width"] == 49
    assert ports["o__payload"]["fields"]["overflow"] == {"offset": 48, "width": 1,
                                                         "signed": False}
    # every port in the description is in the Verilog header with that width
    header = {name: (direction, width) for name, direction, width in
              verilog_ports(text, "fixed_mul")}
    assert header == {p["name"]: (p["direction"], p["width"]) for p in desc["ports"]}


def test_iterative_throughput_is_a_fraction():
    dut = CordicAtan2Iterative(iterations=12)
    desc = describe_block(dut, "it", "x", emit_verilog(dut, "it"))
    assert desc["throughput"] == "1/12"
    assert desc["initiation_interval_cycles"] == 12
    assert desc["latency_cycles"] == 13
    assert desc["parameters"]["iterations"] == 12 and desc["parameters"]["guard_bits"] == 4


@pytest.mark.parametrize("name", ["cordic_atan2", "cordic_atan2_iter", "cordic_sincos",
                                  "goldschmidt_div", "goldschmidt_recip", "fixed_mul"])
def test_emitted_verilog_is_lint_clean(name, tmp_path):
    """verilator --lint-only -Wall: no warning beyond the harness's documented waivers."""
    from navgate.gateware.verify import lint_verilog
    from navgate.hw.blocks import get_block

    path = tmp_path / f"{name}.v"
    path.write_text(emit_verilog(get_block(name).factory(), name))
    assert lint_verilog(path, top=name) == []
