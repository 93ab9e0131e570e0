"""The AXI4-Lite register bank of seed 000's map in Verilator, driven by cocotbext-axi's
AXI-Lite master with random pauses on every channel (navgate.gateware.axi_lite_cocotb):
every register through the Python driver, then 10,000 random transactions against the model."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from navgate.gateware.axi_lite import AxiLiteRegisterBank
from navgate.gateware.verify import run_cocotb
from navgate.hw.regmap import load_rdl

RDL = (Path(__file__).resolve().parents[2] / "src" / "navgate" / "systems" / "ins_trn" / "pl"
       / "registers.rdl")


def run_bank(tmp_path, transactions, seed):
    regmap = load_rdl(RDL)
    job = {"rdl": str(RDL), "seed": seed, "transactions": transactions, "pause_probability": 0.3,
           "status": str(tmp_path / "status.json")}
    (tmp_path / "job.json").write_text(json.dumps(job))
    run_cocotb(AxiLiteRegisterBank(regmap), "navgate.gateware.axi_lite_cocotb",
               top="ins_trn_regs", env={"NAVGATE_AXIL_JOB": str(tmp_path / "job.json")},
               work_dir=tmp_path / "sim")
    status = json.loads((tmp_path / "status.json").read_text())
    assert status["mismatches"] == []
    readable = sum(1 for r in regmap.registers if r.read_mask)
    writable = sum(1 for r in regmap.registers if r.writable)
    assert status["driver_reads"] >= readable + sum(
        1 for r in regmap.registers if r.writable and r.read_mask)
    assert status["driver_writes"] == writable
    assert status["reads"] + status["writes"] == transactions
    # about 5 % unmapped offsets (SLVERR), plus the driver's probe
    assert status["slverr"] > 0.03 * transactions
    assert status["pulses_seen"] > transactions / 1000
    return status


def test_bank_in_verilator_with_random_backpressure(tmp_path):
    run_bank(tmp_path, 2_000, seed=7)


@pytest.mark.slow
def test_bank_in_verilator_10000_transactions(tmp_path):
    run_bank(tmp_path, 10_000, seed=8)
