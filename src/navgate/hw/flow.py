"""The build flow behind ``navgate build`` and ``navgate report``.

``build_block`` turns a registered block into files in the output directory:

- ``BLOCK.v``: the Verilog, top module ``BLOCK`` (deterministic, see :mod:`navgate.hw.verilog`);
- ``BLOCK.json``: ports, latency, throughput and parameters;
- ``BLOCK.utilization.json``: the xc7 cell counts (and, with ``timing=True``, the ECP5 proxy
  Fmax under ``timing``, as before);
- with ``timing=True``, ``BLOCK.timing.json``: the three timing figures, each labelled for what
  it is (see :func:`timing_summary`): ``xc7_logic_path_ns`` (Yosys ``sta``, logic only, with
  the path's start and end points), ``ecp5_fmax_mhz`` and ``nexus_fmax_mhz`` (routed proxies,
  each the mean over its placer seeds, with ``*_fmax_by_seed``).
- with ``asic="sg13g2"``, ``BLOCK.asic.json``: the pre-layout IHP SG13G2 standard-cell figures
  of :func:`navgate.hw.asic.synthesize_asic` (cells, flip-flops, area, smallest TinyTapeout tile);
- whatever else the component delivers through its optional ``write_artifacts(out_dir, name)``
  method (a register bank writes its C header and register documentation), listed under
  ``artifacts`` in ``BLOCK.json``.

Tool work files go to a temporary directory that is removed afterwards, unless ``keep_work``
is given: then they stay in ``OUT/work/BLOCK/``. ``report_table`` formats the rows of every
block as one markdown table.
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from navgate.hw.blocks import get_block
from navgate.hw.synth import (
    ECP5_SEED,
    NEXUS_SEED,
    TARGETS,
    synthesize,
    timing_ecp5,
    timing_nexus,
    timing_xc7,
)
from navgate.hw.verilog import describe_block, emit_verilog

Progress = Callable[[str], None]

#: which timing models ``--timing`` runs (all by default)
TIMING_MODELS = ("xc7", "ecp5", "nexus")


def _write_json(path: Path, content: dict[str, Any]) -> None:
    path.write_text(json.dumps(content, indent=2) + "\n")


def timing_summary(name: str, xc7: dict[str, Any] | None, ecp5: dict[str, Any] | None,
                   nexus: dict[str, Any] | None) -> dict[str, Any]:
    """The contents of ``BLOCK.timing.json`` (``None`` for a model that was not run)."""
    return {
        "block": name,
        "xc7_logic_path_ns": xc7["path_ns"] if xc7 else None,
        "xc7_logic_path_start": xc7["start"] if xc7 else None,
        "xc7_logic_path_end": xc7["end"] if xc7 else None,
        "xc7_logic_path_label": xc7["model"] if xc7 else None,
        "xc7_logic_path_steps": xc7["steps"] if xc7 else None,
        "ecp5_fmax_mhz": ecp5["fmax_mhz"] if ecp5 else None,
        "ecp5_fmax_by_seed": ecp5["fmax_by_seed"] if ecp5 else None,
        "ecp5_label": ("ECP5 routed proxy Fmax: " + ecp5["proxy"]) if ecp5 else None,
        "nexus_fmax_mhz": nexus["fmax_mhz"] if nexus else None,
        "nexus_fmax_by_seed": nexus["fmax_by_seed"] if nexus else None,
        "nexus_router_by_seed": nexus["router_by_seed"] if nexus else None,
        "nexus_label": ("Nexus routed proxy Fmax: " + nexus["proxy"]) if nexus else None,
    }


def build_block(
    name: str,
    out_dir: Path,
    target: str = "xc7z020",
    timing: bool = False,
    progress: Progress | None = None,
    keep_work: bool = False,
    ecp5_seeds: tuple[int, ...] = (ECP5_SEED,),
    nexus_seeds: tuple[int, ...] = (NEXUS_SEED,),
    models: tuple[str, ...] = TIMING_MODELS,
    asic: str | None = None,
    liberty: Path | None = None,
) -> dict[str, Any]:
    """Emit, describe and synthesise block ``name``; returns the merged description."""
    say = progress or (lambda message: None)
    if target not in TARGETS:
        raise KeyError(f"unknown target {target!r}; known targets: {', '.join(TARGETS)}")
    unknown = set(models) - set(TIMING_MODELS)
    if unknown:
        raise KeyError(f"unknown timing model(s) {sorted(unknown)}; known: {TIMING_MODELS}")
    block = get_block(name)
    out_dir = Path(out_dir)
    say(f"{name}: elaborating and emitting Verilog")
    board = TARGETS[target].board
    # on a board, the board variant (its clocking and pins) where the block has one
    component = block.factory(board) if board is not None else block.factory()
    text = emit_verilog(component, name)
    (out_dir / f"{name}.v").write_text(text)
    description = describe_block(component, name, block.description, text)
    description["target"] = target
    # a component may carry more deliverables (a register bank: its C header and docs; a top
    # level on a board target: its constraints and filelist)
    artifacts = getattr(component, "write_artifacts", None)
    if artifacts is not None:
        import inspect

        if "target" in inspect.signature(artifacts).parameters:
            made = artifacts(out_dir, name, target=target)
        else:
            made = artifacts(out_dir, name)
        description["artifacts"] = sorted(p.name for p in made)
    _write_json(out_dir / f"{name}.json", description)
    with tempfile.TemporaryDirectory(prefix=f"navgate-{name}-") as scratch:
        work = out_dir / "work" / name if keep_work else Path(scratch)
        say(f"{name}: synthesising for {target} (yosys synth_xilinx)")
        utilization = synthesize(text, name, target, work / target)
        timing_json = None
        if timing:
            xc7 = ecp5 = nexus = None
            if "xc7" in models:
                say(f"{name}: xc7 static timing (yosys sta, fresh process)")
                xc7 = timing_xc7(name, work / target)
            if "ecp5" in models:
                say(f"{name}: place and route for the ECP5 timing proxy (nextpnr-ecp5)")
                ecp5 = timing_ecp5(text, name, work / "ecp5", seeds=ecp5_seeds)
                utilization["timing"] = ecp5
            if "nexus" in models:
                say(f"{name}: place and route for the Nexus timing proxy (nextpnr-nexus)")
                nexus = timing_nexus(text, name, work / "nexus", seeds=nexus_seeds)
            timing_json = timing_summary(name, xc7, ecp5, nexus)
        asic_json = None
        if asic is not None:
            from navgate.hw.asic import default_liberty, synthesize_asic

            say(f"{name}: mapping to the {asic} standard cells (yosys dfflibmap, abc -liberty)")
            asic_json = synthesize_asic(text, name, work / asic, liberty or default_liberty(),
                                        asic)
    _write_json(out_dir / f"{name}.utilization.json", utilization)
    result = {**description, "utilization": utilization}
    if timing_json is not None:
        _write_json(out_dir / f"{name}.timing.json", timing_json)
        result["timing"] = timing_json
    if asic_json is not None:
        _write_json(out_dir / f"{name}.asic.json", asic_json)
        result["asic"] = asic_json
    return result


COLUMNS = ("block", "LUT", "FF", "DSP", "CARRY4", "BRAM36", "latency", "throughput",
           "xc7 logic path (ns)", "ECP5 routed proxy Fmax (MHz)",
           "Nexus routed proxy Fmax (MHz)")


#: the columns ``navgate report --asic`` adds
ASIC_COLUMNS = ("SG13G2 area (um2)", "SG13G2 FF", "IHP tile (65 %)", "SG13G2 path (ns)")


def _number(value: float | None, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def report_row(built: dict[str, Any]) -> list[str]:
    """One table row from :func:`build_block`'s result."""
    use = built["utilization"]
    timing = built.get("timing") or {}
    return [
        built["block"],
        str(use["lut"]),
        str(use["ff"]),
        str(use["dsp"]),
        str(use["carry4"]),
        str(use["bram36"]),
        str(built["latency_cycles"]),
        built["throughput"],
        _number(timing.get("xc7_logic_path_ns"), 3),
        _number(timing.get("ecp5_fmax_mhz"), 1),
        _number(timing.get("nexus_fmax_mhz"), 1),
    ] + (asic_cells(built["asic"]) if "asic" in built else [])


def asic_cells(asic: dict[str, Any]) -> list[str]:
    """The :data:`ASIC_COLUMNS` entries of one block's ``BLOCK.asic.json``."""
    return [f"{asic['area_um2']:.1f}", str(asic["flip_flops"]), asic["tile"] or "none",
            f"{asic['timing']['longest_path_ns']:.3f}"]


def path_line(built: dict[str, Any]) -> str | None:
    """``block: N ns, START -> END`` for the xc7 logic-only critical path, if it was timed."""
    timing = built.get("timing") or {}
    if timing.get("xc7_logic_path_ns") is None:
        return None
    return (f"{built['block']}: {timing['xc7_logic_path_ns']:.3f} ns, "
            f"{timing['xc7_logic_path_start']} -> {timing['xc7_logic_path_end']}")


#: what each timing column is, printed under a report with timing
TIMING_LEGEND = (
    "xc7 logic path: Yosys sta on the synth_xilinx netlist, prjxray cell delays "
    "(clock-to-out + cells; no routing, no setup). ECP5 / Nexus: routed proxies "
    "(nextpnr-ecp5 LFE5U-85F-6, nextpnr-nexus LIFCL-40-9), achieved Fmax, not Zynq figures."
)


def report_table(rows: list[list[str]], paths: list[str] | None = None) -> str:
    """A markdown table of ``rows`` under :data:`COLUMNS` (and :data:`ASIC_COLUMNS` when the
    rows carry them), then the critical paths if given."""
    columns = COLUMNS + (ASIC_COLUMNS if rows and len(rows[0]) > len(COLUMNS) else ())
    lines = [
        "| " + " | ".join(columns) + " |",
        "|" + "|".join("---" if i == 0 else "---:" for i in range(len(columns))) + "|",
    ]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    if paths:
        lines += ["", TIMING_LEGEND, "", "xc7 logic-only critical paths (start -> end):", ""]
        lines += [f"- {line}" for line in paths]
    return "\n".join(lines) + "\n"
