"""The build flow behind ``navgate build`` and ``navgate report``.

``build_block`` turns a registered block into three files in the output directory:

- ``BLOCK.v``: the Verilog, top module ``BLOCK`` (deterministic, see :mod:`navgate.hw.verilog`);
- ``BLOCK.json``: ports, latency, throughput and parameters;
- ``BLOCK.utilization.json``: the xc7 cell counts and, with ``timing=True``, the ECP5 proxy
  Fmax (see :mod:`navgate.hw.synth`);
- whatever else the component delivers through its optional ``write_artifacts(out_dir, name)``
  method (a register bank writes its C header and register documentation), listed under
  ``artifacts`` in ``BLOCK.json``.

Tool work files go to ``OUT/work/BLOCK/``. ``report_table`` formats the rows of every block as
one markdown table.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from navgate.hw.blocks import get_block
from navgate.hw.synth import TARGETS, synthesize, timing_ecp5
from navgate.hw.verilog import describe_block, emit_verilog

Progress = Callable[[str], None]


def _write_json(path: Path, content: dict[str, Any]) -> None:
    path.write_text(json.dumps(content, indent=2) + "\n")


def build_block(
    name: str,
    out_dir: Path,
    target: str = "xc7z020",
    timing: bool = False,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Emit, describe and synthesise block ``name``; returns the merged description."""
    say = progress or (lambda message: None)
    if target not in TARGETS:
        raise KeyError(f"unknown target {target!r}; known targets: {', '.join(TARGETS)}")
    block = get_block(name)
    out_dir = Path(out_dir)
    say(f"{name}: elaborating and emitting Verilog")
    component = block.factory()
    text = emit_verilog(component, name)
    (out_dir / f"{name}.v").write_text(text)
    description = describe_block(component, name, block.description, text)
    # a component may carry more deliverables (a register bank: its C header and docs)
    artifacts = getattr(component, "write_artifacts", None)
    if artifacts is not None:
        description["artifacts"] = sorted(p.name for p in artifacts(out_dir, name))
    _write_json(out_dir / f"{name}.json", description)
    work = out_dir / "work" / name
    say(f"{name}: synthesising for {target} (yosys synth_xilinx)")
    utilization = synthesize(text, name, target, work / target)
    if timing:
        say(f"{name}: place and route for the ECP5 timing proxy (nextpnr-ecp5)")
        utilization["timing"] = timing_ecp5(text, name, work / "ecp5")
    _write_json(out_dir / f"{name}.utilization.json", utilization)
    return {**description, "utilization": utilization}


COLUMNS = ("block", "LUT", "FF", "DSP", "CARRY4", "BRAM36", "latency", "throughput",
           "Fmax ECP5 proxy (MHz)")


def report_row(built: dict[str, Any]) -> list[str]:
    """One table row from :func:`build_block`'s result."""
    use = built["utilization"]
    timing = use.get("timing")
    fmax = "-" if not timing or timing.get("fmax_mhz") is None else f"{timing['fmax_mhz']:.1f}"
    return [
        built["block"],
        str(use["lut"]),
        str(use["ff"]),
        str(use["dsp"]),
        str(use["carry4"]),
        str(use["bram36"]),
        str(built["latency_cycles"]),
        built["throughput"],
        fmax,
    ]


def report_table(rows: list[list[str]]) -> str:
    """A markdown table of ``rows`` under :data:`COLUMNS`."""
    lines = [
        "| " + " | ".join(COLUMNS) + " |",
        "|" + "|".join("---" if i == 0 else "---:" for i in range(len(COLUMNS))) + "|",
    ]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines) + "\n"
