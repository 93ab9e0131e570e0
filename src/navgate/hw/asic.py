"""Pre-layout standard-cell figures for a block: IHP SG13G2 area, flip-flops and tile fit.

The flow is the one ``../shared/asic/README.md`` gives for the IHP SG13G2 open standard cells
(the process of the TinyTapeout IHP shuttles), run with YoWASP Yosys:

    read_verilog BLOCK.v; synth -flatten -top BLOCK
    dfflibmap -liberty LIB; abc -liberty LIB; opt_clean
    stat -liberty LIB

``area_um2`` is Yosys's ``stat -liberty`` chip area (the sum of the cells' Liberty ``area``),
pre-layout: no clock tree, no buffering for wire load, no hold fixing. ``flip_flops`` counts
the cells whose Liberty description has an ``ff`` group (the library's flip-flops; latches
are counted apart). ``tile`` is the smallest TinyTapeout IHP tile whose area holds the
design at :data:`TILE_DENSITY` (65 %, inside the 60-70 % that still routes), with the tile
sizes from the TinyTapeout support tools as the README quotes them.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from navgate.hw.synth import SynthesisError, run_yosys

#: the Liberty file shipped in ``../shared/asic`` (typical corner, 1.20 V, 25 C)
LIBERTY_NAME = "sg13g2_stdcell_typ_1p20V_25C.lib"

#: the technologies ``--asic`` knows
ASIC_TECHS = ("sg13g2",)

#: TinyTapeout IHP tiles, width x height in um (from ../shared/asic/README.md)
TILES: dict[str, tuple[float, float]] = {
    "1x1": (202.08, 154.98),
    "1x2": (202.08, 313.74),
}

#: placement density at which a tile counts as holding the design
TILE_DENSITY = 0.65

#: the system clock the TinyKalman chip (and TinyTapeout designs generally) run at
CLOCK_MHZ = 10.0


class LibertyMissing(FileNotFoundError):
    """The Liberty file named for ``--asic`` is not there."""


def default_liberty(start: Path | None = None) -> Path:
    """``../shared/asic/<LIBERTY_NAME>`` seen from the working directory (the worktree root)."""
    base = Path.cwd() if start is None else Path(start)
    return base.parent / "shared" / "asic" / LIBERTY_NAME


def liberty_cells(liberty: Path) -> dict[str, dict[str, Any]]:
    """Per cell of ``liberty``: its ``area`` and whether it is a flip-flop or a latch.

    A light scan (the cell headers, their ``area`` attribute and ``ff``/``latch`` groups), not
    a full Liberty parser: enough for the counts above."""
    cells: dict[str, dict[str, Any]] = {}
    current: dict[str, Any] | None = None
    for line in Path(liberty).read_text(errors="replace").splitlines():
        match = re.match(r"\s*cell\s*\(\s*\"?([\w$]+)\"?\s*\)", line)
        if match:
            current = {"area": None, "ff": False, "latch": False}
            cells[match.group(1)] = current
            continue
        if current is None:
            continue
        if current["area"] is None:
            area = re.match(r"\s*area\s*:\s*([0-9.eE+-]+)", line)
            if area:
                current["area"] = float(area.group(1))
        if re.match(r"\s*ff\s*\(", line):
            current["ff"] = True
        elif re.match(r"\s*latch\s*\(", line):
            current["latch"] = True
    return cells


def smallest_tile(area_um2: float, density: float = TILE_DENSITY) -> str | None:
    """The smallest tile of :data:`TILES` whose area at ``density`` holds ``area_um2``."""
    for name, (width, height) in sorted(TILES.items(), key=lambda item: item[1][0] * item[1][1]):
        if area_um2 <= density * width * height:
            return name
    return None


def synthesize_asic(verilog_text: str, top: str, workdir: Path, liberty: Path,
                    tech: str = "sg13g2") -> dict[str, Any]:
    """Map ``top`` to the standard cells of ``liberty``; the summary of ``BLOCK.asic.json``."""
    if tech not in ASIC_TECHS:
        raise KeyError(f"unknown ASIC technology {tech!r}; known: {', '.join(ASIC_TECHS)}")
    liberty = Path(liberty).resolve()
    if not liberty.is_file():
        raise LibertyMissing(f"Liberty file not found: {liberty} (give its path with --liberty)")
    library = liberty_cells(liberty)
    workdir.mkdir(parents=True, exist_ok=True)
    (workdir / f"{top}.v").write_text(verilog_text)
    script = (
        f"read_verilog {top}.v\n"
        f"synth -flatten -top {top}\n"
        f"dfflibmap -liberty {liberty}\n"
        f"abc -liberty {liberty}\n"
        "opt_clean\n"
        f"tee -q -o stat_asic.json stat -json -liberty {liberty}\n"
        f"write_verilog -noattr -norename netlist_{tech}.v\n"
    )
    run_yosys(script, workdir, "yosys_asic.log")
    stat = json.loads((workdir / "stat_asic.json").read_text())["design"]
    cells = {str(k): int(v) for k, v in stat["num_cells_by_type"].items()}
    unmapped = sorted(cell for cell in cells if cell not in library)
    if unmapped:
        raise SynthesisError(f"cells left unmapped to {liberty.name}: {', '.join(unmapped)}")
    area = sum(count * library[cell]["area"] for cell, count in cells.items())
    flip_flops = sum(count for cell, count in cells.items() if library[cell]["ff"])
    latches = sum(count for cell, count in cells.items() if library[cell]["latch"])
    tile = smallest_tile(area)
    tiles = {name: round(100.0 * area / (w * h), 1) for name, (w, h) in TILES.items()}
    return {
        "block": top,
        "tech": tech,
        "liberty": liberty.name,
        "flow": "yosys synth -flatten; dfflibmap -liberty; abc -liberty; stat -liberty",
        "cells": sum(cells.values()),
        "flip_flops": flip_flops,
        "latches": latches,
        "area_um2": round(area, 4),
        "sequential_area_um2": round(sum(count * library[cell]["area"]
                                         for cell, count in cells.items()
                                         if library[cell]["ff"] or library[cell]["latch"]), 4),
        "tile": tile,
        "tile_density": TILE_DENSITY,
        "tile_percent": tiles,
        "cells_by_type": dict(sorted(cells.items())),
    }
