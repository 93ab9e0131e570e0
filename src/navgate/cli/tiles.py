"""`navgate tiles split|info`: cut a DEM into edge-sharing GeoTIFF tiles; describe a tile set.

Both sub-commands follow README's conventions: one-line errors with exit 2, outputs written
through :func:`navgate.cli.common.atomic_output_dir`, a JSON summary beside the printed table.
The tile store itself is :mod:`navgate.trn.tiles`.
"""

from __future__ import annotations

import math
import re

import click

from navgate.cli.common import (
    CliError,
    atomic_output_dir,
    consoles,
    default_out_dir,
    out_option,
    write_summary,
)


@click.group()
def tiles():
    """DEM tile directories (for `navgate fly --dem DIR`)."""


def _grid(value: str):
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", value)
    if not m or int(m[1]) < 1 or int(m[2]) < 1:
        raise CliError(f"--into must be ROWSxCOLS with positive counts (e.g. 2x2), got {value!r}")
    return int(m[1]), int(m[2])


def _describe(dem, index=None):
    sn, se = dem.post_spacing_m()
    s, n, w, e = dem.lat_south, dem.lat_north, dem.lon_west, dem.lon_east
    out = {"posts": list(dem.shape), "post_spacing_m": [sn, se],
           "post_spacing_arcsec": [math.degrees(dem.dlat) * 3600, math.degrees(dem.dlon) * 3600],
           "bounds_deg": {"south": math.degrees(s), "north": math.degrees(n),
                          "west": math.degrees(w), "east": math.degrees(e)},
           "void_fraction": dem.void_fraction(), "bytes": int(dem.heights.nbytes)}
    if index is not None:
        out["tiles"] = [{"name": t.name, "posts": list(t.shape), "offset_posts": list(o),
                         "void_fraction": t.void_fraction()}
                        for t, o in zip(index.tiles, index.offsets, strict=True)]
        out["gap_posts"] = index.gap_posts
    return out


def _print(console, title, info):
    from rich.table import Table

    table = Table(title=title)
    table.add_column("figure")
    table.add_column("value", justify="right")
    table.add_row("posts", " x ".join(map(str, info["posts"])))
    table.add_row("post spacing (m, N x E)", "{:.2f} x {:.2f}".format(*info["post_spacing_m"]))
    b = info["bounds_deg"]
    table.add_row("bounds (deg)", f"{b['south']:.5f}..{b['north']:.5f} N, "
                  f"{b['west']:.5f}..{b['east']:.5f} E")
    table.add_row("void fraction", f"{info['void_fraction']:.4%}")
    if "tiles" in info:
        table.add_row("tiles", str(len(info["tiles"])))
        table.add_row("gap posts (no tile)", str(info["gap_posts"]))
    table.add_row("merged size (MiB)", f"{info['bytes'] / 2**20:.3f}")
    console.print(table)


@tiles.command()
@click.argument("dem_path", metavar="DEM")
@click.option("--into", "into", default="2x2", show_default=True, help="ROWSxCOLS tiles.")
@out_option(default_out_dir("tiles-split"), "Tile directory (written atomically).")
@click.option("--quiet", is_flag=True, help="No table.")
def split(dem_path, into, out, quiet):
    """Split DEM (a file, or `default` for the embedded DEM) into GeoTIFF tiles sharing edges."""
    from navgate.trn import tiles as store
    from navgate.trn.dem import DemError

    rows, cols = _grid(into)
    table_console, _ = consoles(quiet)
    try:
        dem = store.open_terrain(dem_path)
        store.split_bounds(dem.shape[0], rows)
        store.split_bounds(dem.shape[1], cols)
    except DemError as error:
        raise CliError(str(error)) from None
    with atomic_output_dir(out, inputs=[dem_path]) as stage:
        paths = store.split(dem, rows, cols, stage)
        summary = {"source": dem.name, "into": [rows, cols],
                   "tile_files": [p.name for p in paths], **_describe(dem)}
        write_summary(stage, summary, name="tiles_summary.json")
    _print(table_console, f"{dem.name} -> {rows} x {cols} tiles in {out}", summary)


@tiles.command()
@click.argument("tile_dir", metavar="DIR", type=click.Path(file_okay=False))
@click.option("--priority", type=click.Choice(["agree", "first"]), default="agree",
              show_default=True, help="Shared edge posts must agree, or the first-named wins.")
@out_option(default_out_dir("tiles-info"), "Where the JSON summary goes (written atomically).")
@click.option("--quiet", is_flag=True, help="No table.")
def info(tile_dir, priority, out, quiet):
    """Coverage, post spacing, voids and gaps of a tile directory."""
    from navgate.trn import tiles as store
    from navgate.trn.dem import DemError

    table_console, _ = consoles(quiet)
    try:
        index = store.index_tiles(tile_dir)
        dem = store.mosaic(index, priority=priority, name=str(tile_dir))
    except DemError as error:
        raise CliError(str(error)) from None
    summary = {"directory": str(tile_dir), "priority": priority, **_describe(dem, index)}
    with atomic_output_dir(out, inputs=[tile_dir]) as stage:
        write_summary(stage, summary)
    _print(table_console, f"tile set {tile_dir}", summary)
