"""``navgate tiles``: make and inspect DEM tile directories (the Pi's DTED cache of seed 000).

- ``navgate tiles split DEM --into RxC --out DIR`` cuts a DEM (a file, or ``default`` for the
  embedded Jacksboro DEM) into R x C GeoTIFF tiles that share their edge posts, as DTED and
  SRTM cells do, on exactly the DEM's lattice: a flight over DIR equals the flight over the DEM.
- ``navgate tiles info DIR`` indexes a tile directory and prints its coverage, post spacing,
  gaps, voids and overlaps, and the tile cache a route needs; ``--out`` writes the same as
  ``tiles.json``.

The store itself is :mod:`navgate.trn.tiles`.
"""

from __future__ import annotations

import math
import re

import click

from navgate.cli.console import consoles
from navgate.cli.errors import CliError
from navgate.cli.inputs import dem_input
from navgate.cli.outputs import (
    atomic_output_dir,
    check_out_dir,
    check_outputs_early,
    default_out_dir,
    out_option,
    staged_outputs,
)
from navgate.cli.summary import write_summary


@click.group()
def tiles():
    """Make and inspect DEM tile directories (navgate fly --dem DIR, navgate trn-serve)."""


def _grid(ctx, param, value):
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", value or "")
    if not match:
        raise click.BadParameter(f"must be ROWSxCOLS, e.g. 2x2, got {value!r}")
    rows, cols = int(match.group(1)), int(match.group(2))
    if not (1 <= rows <= 256 and 1 <= cols <= 256):
        raise click.BadParameter(f"tile counts must be between 1 and 256, got {value}")
    return rows, cols


@tiles.command()
@click.argument("dem_path", metavar="DEM")
@click.option("--into", "grid", required=True, callback=_grid,
              help="Tile counts ROWSxCOLS (e.g. 3x3).")
@out_option(default_out_dir("tiles"), "Tile directory to write (written atomically).")
@click.option("--quiet", is_flag=True, help="No table.")
def split(dem_path, grid, out, quiet):
    """Cut DEM (a file, or 'default' for the embedded DEM) into tiles sharing edge posts."""
    from navgate.cli.extras import require

    require("rasterio", "navgate tiles split")  # it writes GeoTIFF tiles
    from navgate.trn.dem import Dem, DemError
    from navgate.trn.tiles import TileStore, split_dem

    table_console, console = consoles(quiet)
    try:
        dem = Dem.default() if dem_path == "default" else Dem.from_file(dem_input(dem_path))
    except DemError as error:
        raise CliError(str(error)) from None
    check_out_dir(out)
    rows, cols = grid
    inputs = [] if dem_path == "default" else [dem_path]
    check_outputs_early(out, ["tiles.json"], inputs)
    # the new tiles replace the directory's tiles as a whole (tiles of an earlier split that
    # this one does not write would overlap the new ones); staged: a failed split leaves the
    # directory as it was
    with staged_outputs(out, inputs=inputs, replaces=_is_tile) as staging:
        stage = staging.dir
        try:
            paths = split_dem(dem, rows, cols, stage)
        except ValueError as error:
            raise CliError(str(error)) from None
        summary = _describe(TileStore(stage))
        summary["directory"] = str(out)  # the final directory, not the staging one
        summary["source"] = dem.name
        write_summary(stage, summary, name="tiles.json")
    table_console.print(f"{len(paths)} tiles of {dem.name} ({dem.shape[0]} x {dem.shape[1]} "
                        f"posts) cut {rows} x {cols}, sharing their edge posts")
    console.print(f"wrote {len(paths)} tiles and tiles.json in {out}", highlight=False)


def _is_tile(path) -> bool:
    from navgate.trn.tiles import TILE_SUFFIXES

    return path.suffix.lower() in TILE_SUFFIXES


def _describe(store) -> dict:
    scan = store.scan()
    sn, se = store.post_spacing_m()
    south, north, west, east = store.valid_bounds()
    largest = max(t.nbytes for t in store.tiles)
    return {
        "directory": str(store.directory),
        "tiles": [{"file": t.path.name, "row0": t.row0, "col0": t.col0, "rows": t.rows,
                   "cols": t.cols, "bytes": t.nbytes} for t in store.tiles],
        "tile_count": len(store.tiles),
        "posts": list(store.shape),
        "post_spacing_arcsec": [math.degrees(store.dlat) * 3600, math.degrees(store.dlon) * 3600],
        "post_spacing_m": [sn, se],
        "coverage_deg": {"south": math.degrees(south), "north": math.degrees(north),
                         "west": math.degrees(west), "east": math.degrees(east)},
        "gap_posts": store.gap_posts,
        "void_posts": scan["void_posts"],
        "void_fraction": store.void_fraction(),
        "height_range_m": [scan["min_m"], scan["max_m"]],
        "overlapping_pairs": len(store.overlapping_pairs),
        "overlaps_agree": True,  # scan() assembled every post through the "check" rule
        "size_bytes": store.size_bytes,
        "largest_tile_bytes": largest,
        # a route crossing a tile corner needs the four tiles around it at once
        "route_cache_bytes": min(4 * largest, store.size_bytes),
    }


@tiles.command()
@click.argument("directory", type=click.Path(file_okay=False))
@out_option(None, "Also write tiles.json into this directory (written atomically).")
@click.option("--quiet", is_flag=True, help="No table.")
def info(directory, out, quiet):
    """Index a tile directory: coverage, spacing, gaps, voids, the cache a route needs."""
    from rich.table import Table

    from navgate.trn.dem import DemError
    from navgate.trn.tiles import TileStore

    table_console, console = consoles(quiet)
    if out is not None:
        check_out_dir(out)
        check_outputs_early(out, ["tiles.json"], [directory])
    try:
        store = TileStore(directory)
        summary = _describe(store)
    except DemError as error:
        raise CliError(str(error)) from None
    mib = 2.0**20
    table = Table(title=f"tiles in {directory}")
    table.add_column("")
    table.add_column("")
    cov = summary["coverage_deg"]
    for key, value in (
            ("tiles", f"{summary['tile_count']}"),
            ("posts", f"{summary['posts'][0]} x {summary['posts'][1]}"),
            ("post spacing", "{:.4g} x {:.4g} arc-s ({:.1f} x {:.1f} m)".format(
                *summary["post_spacing_arcsec"], *summary["post_spacing_m"])),
            ("coverage", f"{cov['south']:.5f} to {cov['north']:.5f} N, "
                         f"{cov['west']:.5f} to {cov['east']:.5f} E"),
            ("gaps", f"{summary['gap_posts']} posts"),
            ("voids", f"{summary['void_posts']} posts"),
            ("without a height", f"{100 * summary['void_fraction']:.3g} % of the grid "
                                 "(voids and gaps)"),
            ("heights", "{:.1f} to {:.1f} m".format(*summary["height_range_m"])),
            ("overlapping tile pairs", f"{summary['overlapping_pairs']} (shared posts agree)"),
            ("size in memory", f"{summary['size_bytes'] / mib:.2f} MiB"),
            ("cache a route needs", f"{summary['route_cache_bytes'] / mib:.2f} MiB "
                                    "(the 4 tiles around a corner)")):
        table.add_row(key, value)
    table_console.print(table)
    if out is not None:
        with atomic_output_dir(out, inputs=[directory]) as stage:
            write_summary(stage, summary, name="tiles.json")
        console.print(f"wrote tiles.json in {out}", highlight=False)
