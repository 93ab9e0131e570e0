"""``navgate build`` and ``navgate report``: Verilog, block descriptions and resource figures.

``navgate build BLOCK [--target xc7z020] [--out DIR] [--timing]`` writes ``DIR/BLOCK.v``,
``DIR/BLOCK.json`` and ``DIR/BLOCK.utilization.json``; ``navgate build --list`` names the blocks.
``navgate report [--timing] [--out FILE]`` synthesises every block and prints one markdown
table. The flow itself lives in :mod:`navgate.hw.flow`.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import click
from rich.console import Console
from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

from navgate.cli.common import CliError, prepare_out_dir

DEFAULT_TARGET = "xc7z020"


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


def _run_build(name: str, out_dir: Path, target: str, timing: bool, progress: Progress, task):
    from navgate.hw.flow import build_block
    from navgate.hw.synth import SynthesisError

    def say(message: str) -> None:
        progress.update(task, description=message)

    try:
        return build_block(name, out_dir, target=target, timing=timing, progress=say)
    except SynthesisError as error:
        raise CliError(str(error)) from None
    except OSError as error:
        raise CliError(f"cannot write build outputs in {out_dir}: {error.strerror}") from None


@click.command()
@click.argument("block", required=False)
@click.option("--target", default=DEFAULT_TARGET, show_default=True, help="synthesis target")
@click.option("--out", "out", default="build/hw", show_default=True, help="output directory")
@click.option("--timing", is_flag=True, help="also place and route for the ECP5 Fmax proxy")
@click.option("--list", "list_", is_flag=True, help="list the blocks and exit")
def build(block: str | None, target: str, out: str, timing: bool, list_: bool) -> None:
    """Emit Verilog for BLOCK, describe it and synthesise it for resource figures."""
    from navgate.hw.blocks import all_blocks

    blocks = all_blocks()
    if list_:
        width = max(len(name) for name in blocks)
        for name, entry in blocks.items():
            click.echo(f"{name:<{width}}  {entry.description}")
        return
    if block is None:
        raise CliError("missing BLOCK (use --list to see the blocks)")
    if block not in blocks:
        raise CliError(f"unknown block {block!r}; known blocks: {', '.join(blocks)}")
    _check_target(target)
    out_dir = prepare_out_dir(out)
    if not os.access(out_dir, os.W_OK):
        raise CliError(f"output directory {out_dir} is not writable")
    console = Console(stderr=True)
    console.print(f"[dim]{_yowasp_note()}[/dim]")
    with _progress(console) as progress:
        task = progress.add_task(block, total=1)
        built = _run_build(block, out_dir, target, timing, progress, task)
        progress.advance(task)
    use = built["utilization"]
    fmax = use.get("timing", {}).get("fmax_mhz")
    click.echo(
        f"{block}: LUT {use['lut']}, FF {use['ff']}, DSP {use['dsp']}, CARRY4 {use['carry4']}, "
        f"BRAM36 {use['bram36']}, latency {built['latency_cycles']}, "
        f"throughput {built['throughput']}/cycle"
        + (f", Fmax {fmax:.1f} MHz (ECP5 proxy)" if fmax is not None else "")
    )
    for suffix in (".v", ".json", ".utilization.json"):
        click.echo(f"wrote {out_dir / (block + suffix)}")


def _yowasp_note() -> str:
    from navgate.hw.synth import YOWASP_NOTE

    return YOWASP_NOTE


def report_markdown(timing: bool, target: str, console: Console) -> str:
    """Build every block in a scratch directory and return the markdown table."""
    from navgate.hw.blocks import all_blocks
    from navgate.hw.flow import report_row, report_table

    blocks = list(all_blocks())
    rows = []
    console.print(f"[dim]{_yowasp_note()}[/dim]")
    with tempfile.TemporaryDirectory(prefix="navgate-report-") as scratch:
        with _progress(console) as progress:
            task = progress.add_task("report", total=len(blocks))
            for name in blocks:
                out_dir = Path(scratch) / name
                out_dir.mkdir()
                rows.append(report_row(_run_build(name, out_dir, target, timing, progress, task)))
                progress.advance(task)
    return report_table(rows)


@click.command()
@click.option("--timing", is_flag=True, help="add the ECP5 proxy Fmax column (place and route)")
@click.option("--target", default=DEFAULT_TARGET, show_default=True, help="synthesis target")
@click.option("--out", "out", default=None, help="also write the table to this file")
def report(timing: bool, target: str, out: str | None) -> None:
    """Synthesise every block and print one markdown table of resources and timing."""
    _check_target(target)
    out_path = Path(out) if out is not None else None
    if out_path is not None:
        parent = out_path.parent if str(out_path.parent) else Path(".")
        if out_path.is_dir():
            raise CliError(f"--out {out_path} is a directory, expected a file")
        if not parent.is_dir() or not os.access(parent, os.W_OK):
            raise CliError(f"cannot write {out_path}: directory {parent} missing or not writable")
    table = report_markdown(timing, target, Console(stderr=True))
    click.echo(table, nl=False)
    if out_path is not None:
        try:
            out_path.write_text(table)
        except OSError as error:
            raise CliError(f"cannot write {out_path}: {error.strerror}") from None
