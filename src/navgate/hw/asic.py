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

``timing`` is the longest register-to-register (or port) path by :func:`longest_path`, a
static timing pass over the mapped netlist with the library's NLDM delay and transition
tables, against the 10 MHz clock of a TinyTapeout design. Hand-written because the YoWASP
Yosys build reports no Liberty timing (its ``sta`` knows only ``$specify`` cell models, and
ABC's ``stime`` report does not reach the Yosys log) and OpenSTA is not on PyPI; the pass is
deliberately simple and pessimistic (worse of rise and fall on every arc).
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
        "delete t:$scopeinfo\n"  # hierarchy markers a flattened design keeps (no cells)
        "opt_clean\n"
        f"tee -q -o stat_asic.json stat -json -liberty {liberty}\n"
        f"write_verilog -noattr -norename netlist_{tech}.v\n"
        f"write_json netlist_{tech}.json\n"
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
        "timing": longest_path(workdir / f"netlist_{tech}.json", top, liberty),
        "flip_flops_by_register": flip_flops_by_register(
            workdir / f"netlist_{tech}.json", top,
            {cell for cell, entry in library.items() if entry["ff"]}),
        "cells_by_type": dict(sorted(cells.items())),
    }


def flip_flops_by_register(netlist_json: Path, top: str, ff_types: set[str]) -> dict[str, int]:
    """Flip-flops per register: each flip-flop cell counted under the name of the net on its
    output (bit index dropped; a flip-flop whose output has no public name is ``(unnamed)``),
    largest first. What the area in flip-flops is spent on."""
    module = json.loads(Path(netlist_json).read_text())["modules"][top]
    names: dict[Any, str] = {}
    for name, net in module["netnames"].items():
        if net.get("hide_name") or name.startswith("$"):
            continue
        for bit in net["bits"]:
            names.setdefault(bit, name)
    counts: dict[str, int] = {}
    for cell in module["cells"].values():
        if cell["type"] not in ff_types:
            continue
        outputs = [bit for pin in ("Q", "Q_N") for bit in cell["connections"].get(pin, [])]
        name = next((names[bit] for bit in outputs if bit in names), "(unnamed)")
        counts[name] = counts.get(name, 0) + 1
    return dict(sorted(counts.items(), key=lambda item: (-item[1], item[0])))


# --- timing: a static timing pass over the mapped netlist with the Liberty NLDM tables -------

#: input transition (ns) assumed at the primary inputs and on the ideal clock (the tables' first
#: index point)
INPUT_SLEW_NS = 0.0186


def _floats(text: str) -> list[float]:
    return [float(v) for v in re.findall(r"[-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?", text)]


def _table(lines: list[str], start: int) -> tuple[dict[str, Any], int]:
    """The table group opening at ``lines[start]``: its index_1, index_2 and values."""
    table: dict[str, Any] = {}
    depth, i, body = 0, start, []
    while True:
        line = lines[i]
        depth += line.count("{") - line.count("}")
        body.append(line)
        i += 1
        if depth <= 0:
            break
    text = " ".join(body)
    for key in ("index_1", "index_2"):
        match = re.search(key + r"\s*\(\s*\"([^\"]*)\"", text)
        if match:
            table[key] = _floats(match.group(1))
    match = re.search(r"values\s*\((.*)\)\s*;", text)
    rows = re.findall(r"\"([^\"]*)\"", match.group(1)) if match else []
    table["values"] = [_floats(row) for row in rows]
    return table, i


def liberty_timing(liberty: Path, wanted: set[str]) -> dict[str, dict[str, Any]]:
    """For each cell in ``wanted``: pins (direction, capacitance) and timing arcs of the output
    pins (related pin, timing type, cell_rise/cell_fall/rise_transition/fall_transition
    tables), and the setup tables of the data pins. A line-oriented reader of this library's
    layout (one attribute or group header per line), not a general Liberty parser."""
    lines = Path(liberty).read_text(errors="replace").splitlines()
    cells: dict[str, dict[str, Any]] = {}
    cell = pin = arc = None
    i = 0
    while i < len(lines):
        line = lines[i]
        match = re.match(r"\s*cell\s*\(\s*\"?([\w$]+)\"?\s*\)", line)
        if match:
            name = match.group(1)
            cell = {"pins": {}} if name in wanted else None
            if cell is not None:
                cells[name] = cell
            pin = arc = None
            i += 1
            continue
        if cell is None:
            i += 1
            continue
        match = re.match(r"\s*pin\s*\(\s*\"?(\w+)\"?\s*\)", line)
        if match:
            pin = {"direction": None, "capacitance": 0.0, "arcs": [], "clock": False}
            cell["pins"][match.group(1)] = pin
            arc = None
        elif pin is not None:
            if re.match(r"\s*direction\s*:", line):
                pin["direction"] = line.split(":")[1].strip(" ;\"")
            elif re.match(r"\s*capacitance\s*:", line):
                pin["capacitance"] = float(_floats(line.split(":")[1])[0])
            elif re.match(r"\s*clock\s*:\s*true", line):
                pin["clock"] = True
            elif re.match(r"\s*timing\s*\(", line):
                arc = {"related": None, "type": "combinational", "tables": {}}
                pin["arcs"].append(arc)
            elif arc is not None and re.match(r"\s*related_pin\s*:", line):
                arc["related"] = line.split(":")[1].strip(" ;\"")
            elif arc is not None and re.match(r"\s*timing_type\s*:", line):
                arc["type"] = line.split(":")[1].strip(" ;\"")
            else:
                match = re.match(r"\s*(cell_rise|cell_fall|rise_transition|fall_transition|"
                                 r"rise_constraint|fall_constraint)\s*\(", line)
                if arc is not None and match:
                    arc["tables"][match.group(1)], i = _table(lines, i)
                    continue
        i += 1
    return cells


def _lookup(table: dict[str, Any], x: float, y: float) -> float:
    """Bilinear interpolation (extrapolation past the edges) of an NLDM table."""
    def axis(index: list[float], v: float) -> tuple[int, float]:
        if len(index) < 2:
            return 0, 0.0
        k = 0
        while k < len(index) - 2 and v > index[k + 1]:
            k += 1
        return k, (v - index[k]) / (index[k + 1] - index[k])

    values = table["values"]
    i, fx = axis(table.get("index_1", [x]), x)
    if len(values) == 1:  # one row: a table over index_1 only (stored as one row)
        row = values[0]
        if len(row) < 2:
            return row[0]
        return row[i] + fx * (row[i + 1] - row[i])
    j, fy = axis(table.get("index_2", [y]), y)
    v00, v01 = values[i][j], values[i][j + 1]
    v10, v11 = values[i + 1][j], values[i + 1][j + 1]
    return (v00 * (1 - fx) * (1 - fy) + v01 * (1 - fx) * fy + v10 * fx * (1 - fy)
            + v11 * fx * fy)


def longest_path(netlist_json: Path, top: str, liberty: Path,
                 clock_mhz: float = CLOCK_MHZ) -> dict[str, Any]:
    """Static timing of the mapped netlist from the Liberty NLDM tables.

    Register (clock-to-Q) and input-port paths through the combinational cells to register
    D inputs (plus setup) and output ports. Each net's load is the sum of its sink pins'
    capacitance (no wire load: pre-layout); each arc uses the worse of rise and fall, with
    the worse of the rise/fall output transitions propagated, so the figure errs long. The
    clock is ideal (no tree, no skew)."""
    module = json.loads(Path(netlist_json).read_text())["modules"][top]
    used = {c["type"] for c in module["cells"].values()}
    lib = liberty_timing(liberty, used)
    load: dict[Any, float] = {}
    drivers: dict[Any, tuple[str, str]] = {}
    for cname, c in module["cells"].items():
        pins = lib[c["type"]]["pins"]
        for pname, bits in c["connections"].items():
            for bit in bits:
                if pins[pname]["direction"] == "output":
                    drivers[bit] = (cname, pname)
                else:
                    load[bit] = load.get(bit, 0.0) + pins[pname]["capacitance"]
    arrival: dict[Any, tuple[float, float, str]] = {}  # bit -> (time, slew, start point)
    for pname, port in module["ports"].items():
        if port["direction"] == "input":
            for bit in port["bits"]:
                arrival[bit] = (0.0, INPUT_SLEW_NS, f"input {pname}")

    def arc_out(arc, slew_in, cap):
        t = arc["tables"]
        delay = max(_lookup(t[k], slew_in, cap) for k in ("cell_rise", "cell_fall") if k in t)
        slew = max(_lookup(t[k], slew_in, cap) for k in ("rise_transition", "fall_transition")
                   if k in t)
        return delay, slew

    names = {}
    for nname, net in module["netnames"].items():
        for k, bit in enumerate(net["bits"]):
            if not nname.startswith("$") and bit not in names:
                names[bit] = nname if len(net["bits"]) == 1 else f"{nname}[{k}]"
    # flip-flop outputs start paths at clock-to-Q
    sequential = set()
    for cname, c in module["cells"].items():
        pins = lib[c["type"]]["pins"]
        for pname, pin in pins.items():
            for arc in pin["arcs"]:
                if arc["type"] in ("rising_edge", "falling_edge") and pname in c["connections"]:
                    sequential.add(cname)
                    for bit in c["connections"][pname]:
                        delay, slew = arc_out(arc, INPUT_SLEW_NS, load.get(bit, 0.0))
                        old = arrival.get(bit)
                        if old is None or delay > old[0]:
                            label = names.get(bit, cname)
                            arrival[bit] = (delay, slew, f"{label} (clock-to-Q)")

    def resolve(bit, stack=()):
        if isinstance(bit, str) or bit in arrival:  # constant or known
            return arrival.get(bit, (0.0, INPUT_SLEW_NS, "constant"))
        if bit not in drivers:
            return (0.0, INPUT_SLEW_NS, "undriven")
        cname, pname = drivers[bit]
        c = module["cells"][cname]
        pins = lib[c["type"]]["pins"]
        best = (0.0, INPUT_SLEW_NS, "constant")
        for arc in pins[pname]["arcs"]:
            if arc["type"] not in ("combinational", "combinational_rise",
                                   "combinational_fall") or arc["related"] not in c["connections"]:
                continue
            for src in c["connections"][arc["related"]]:
                t_in, s_in, start = resolve(src)
                delay, slew = arc_out(arc, s_in, load.get(bit, 0.0))
                if t_in + delay > best[0]:
                    best = (t_in + delay, slew, start)
        arrival[bit] = best
        return best

    import sys

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 100000))
    worst = (0.0, "-", "-")
    for cname, c in module["cells"].items():
        if cname not in sequential:
            continue
        pins = lib[c["type"]]["pins"]
        for pname, pin in pins.items():
            setup = [a for a in pin["arcs"] if a["type"] in ("setup_rising", "setup_falling")]
            if not setup or pname not in c["connections"]:
                continue
            for bit in c["connections"][pname]:
                t, slew, start = resolve(bit)
                need = max(_lookup(a["tables"][k], slew, INPUT_SLEW_NS)
                           for a in setup for k in ("rise_constraint", "fall_constraint")
                           if k in a["tables"])
                if t + need > worst[0]:
                    q_bits = [b for q, pin_q in pins.items() if pin_q["direction"] == "output"
                              for b in c["connections"].get(q, [])]
                    register = next((names[b] for b in q_bits if b in names), cname)
                    worst = (t + need, start, f"{register} (D, setup)")
    for pname, port in module["ports"].items():
        if port["direction"] == "output":
            for bit in port["bits"]:
                t, _, start = resolve(bit)
                if t > worst[0]:
                    worst = (t, start, f"output {pname}")
    period = 1000.0 / clock_mhz
    return {
        "longest_path_ns": round(worst[0], 4),
        "path_start": worst[1],
        "path_end": worst[2],
        "clock_mhz": clock_mhz,
        "slack_ns": round(period - worst[0], 4),
        "timing_model": ("Liberty NLDM tables, worse of rise/fall per arc, pin-capacitance "
                         "loads, no wire load, ideal clock (pre-layout)"),
    }
