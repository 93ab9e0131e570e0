"""``navgate cache``: where navgate keeps its build caches, how big they are, and clearing them.

- ``navgate cache info`` prints the cache root and, per kind (``verilog``, ``verilator``,
  ``synth``), its directory, size and entry count (a table on stdout; ``--json`` prints the
  same as one JSON object instead).
- ``navgate cache clear [--kind K]`` removes every entry (of one kind with ``--kind``) and
  says what it removed. It refuses a kind directory outside the cache root (a
  ``$NAVGATE_VERILATOR_CACHE`` elsewhere, or a symbolic link out of the root).

The caches themselves are :mod:`navgate.cache`. The command writes no output files, so it has
no ``--out``; errors are one line on stderr with exit status 2, as for every command.
"""

from __future__ import annotations

import json

import click

from navgate.cli.console import consoles
from navgate.cli.errors import CliError


def _size(n: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n} B"


@click.group()
def cache():
    """Show or clear navgate's build caches (Verilog, Verilator models, synthesis results)."""


@cache.command()
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead.")
def info(as_json):
    """Print the cache root and each kind's directory, size and entry count."""
    from navgate import cache as store

    root = store.cache_root()
    kinds = store.info()
    for path in (root, *(k.path for k in kinds)):  # a file there is no cache: never "0 entries"
        if path.exists() and not path.is_dir():
            raise CliError(f"cache directory {path} is not a directory (check "
                           f"${store.ENV_ROOT})")
    if as_json:
        click.echo(json.dumps({
            "root": str(root),
            "kinds": {k.kind: {"path": str(k.path), "bytes": k.bytes, "entries": k.entries}
                      for k in kinds},
        }, indent=2))
        return
    table, _ = consoles()
    from rich.table import Table

    grid = Table(title=f"navgate cache: {root}", title_justify="left")
    for column in ("kind", "directory", "size", "entries"):
        grid.add_column(column, justify="right" if column in ("size", "entries") else "left")
    for k in kinds:
        grid.add_row(k.kind, str(k.path), _size(k.bytes), str(k.entries))
    grid.add_row("all", "", _size(sum(k.bytes for k in kinds)),
                 str(sum(k.entries for k in kinds)))
    table.print(grid)


@cache.command()
@click.option("--kind", type=click.Choice(["verilog", "verilator", "synth"]), default=None,
              help="Clear only this kind (default: all).")
def clear(kind):
    """Remove every cache entry (of one kind with --kind)."""
    from navgate import cache as store

    try:
        removed = store.clear(kind)
    except store.CacheError as error:
        raise CliError(str(error)) from None
    if not removed:
        click.echo(f"nothing to clear in {store.cache_root()}", err=True)
    for k in removed:
        click.echo(f"cleared {k.kind}: {k.entries} entries, {_size(k.bytes)} ({k.path})",
                   err=True)
