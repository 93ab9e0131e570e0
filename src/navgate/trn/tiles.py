"""DEM tile directories: index, validation, mosaic, and splitting a DEM into tiles.

A tile directory holds DTED (.dt0/.dt1/.dt2), SRTM (.hgt) and GeoTIFF (.tif/.tiff) tiles, mixed
allowed, each read by :meth:`navgate.trn.dem.Dem.from_file` (same post-centre convention). The
tiles must share one post spacing and lie on one post grid; neighbours may share their edge posts
(DTED/SRTM style), and shared posts must agree (NaN voids agree with NaN) unless ``priority``
names the rule for which tile wins (``"first"``: the tile whose file name sorts first). Gaps
between tiles are filled with NaN voids, which the bilinear kernel reports as "no terrain" (TRN
pauses and counts the rejection); they are reported by :func:`index_tiles`, never zero-filled.

:func:`open_terrain` is the one entry point for a DEM path, a file or a tile directory, and
returns a :class:`Dem`; for a directory it is the merged raster, so heights and gradients across
a tile edge are those of the whole DEM bit for bit (same kernels on the same array).

Scope note: this version assembles the whole mosaic in memory; an on-demand LRU tile cache with a
byte cap (issue 27, item 1) is not implemented yet (``cache_mb`` is accepted and checked only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from navgate.trn.dem import Dem, DemError

TILE_SUFFIXES = (".dt0", ".dt1", ".dt2", ".hgt", ".tif", ".tiff")
#: tolerance on post alignment, in posts: header coordinates pass through degrees in text/float
ALIGN_TOL_POSTS = 1e-6
PRIORITIES = ("agree", "first")


@dataclass
class TileIndex:
    """Tiles placed on a common post grid."""

    tiles: list  # list[Dem]
    offsets: list  # list[(row, col)] of each tile's post (0, 0) in the mosaic
    shape: tuple
    lat_north: float
    lon_west: float
    dlat: float
    dlon: float
    gap_posts: int  # mosaic posts covered by no tile


def _tile_paths(directory: Path):
    paths = sorted(p for p in directory.iterdir()
                   if p.is_file() and p.suffix.lower() in TILE_SUFFIXES)
    if not paths:
        raise DemError(f"{directory}: no DEM tiles (looked for {', '.join(TILE_SUFFIXES)})")
    return paths


def index_tiles(directory) -> TileIndex:
    """Read and place every tile of ``directory``; DemError on mixed spacing or misalignment."""
    directory = Path(directory)
    if not directory.is_dir():
        raise DemError(f"tile directory not found: {directory}")
    tiles = [Dem.from_file(p) for p in _tile_paths(directory)]
    ref = tiles[0]
    for t in tiles[1:]:
        if (abs(t.dlat - ref.dlat) > ALIGN_TOL_POSTS * ref.dlat
                or abs(t.dlon - ref.dlon) > ALIGN_TOL_POSTS * ref.dlon):
            raise DemError(
                f"{directory}: tiles of different post spacing: {ref.name} "
                f"{math.degrees(ref.dlat) * 3600:.4g}\" x {math.degrees(ref.dlon) * 3600:.4g}\", "
                f"{t.name} {math.degrees(t.dlat) * 3600:.4g}\" x "
                f"{math.degrees(t.dlon) * 3600:.4g}\"")
    north = max(tiles, key=lambda t: t.lat_north)
    west = min(tiles, key=lambda t: t.lon_west)
    lat_north, lon_west = north.lat_north, west.lon_west
    offsets = []
    for t in tiles:
        fr = (lat_north - t.lat_north) / ref.dlat
        fc = (t.lon_west - lon_west) / ref.dlon
        r, c = round(fr), round(fc)
        if abs(fr - r) > ALIGN_TOL_POSTS or abs(fc - c) > ALIGN_TOL_POSTS:
            raise DemError(f"{directory}: tile {t.name} is not on the post grid of "
                           f"{ref.name} (offset {fr:.4f} x {fc:.4f} posts)")
        offsets.append((r, c))
    nrow = max(r + t.shape[0] for t, (r, _) in zip(tiles, offsets, strict=True))
    ncol = max(c + t.shape[1] for t, (_, c) in zip(tiles, offsets, strict=True))
    covered = np.zeros((nrow, ncol), bool)
    for t, (r, c) in zip(tiles, offsets, strict=True):
        covered[r:r + t.shape[0], c:c + t.shape[1]] = True
    return TileIndex(tiles, offsets, (nrow, ncol), lat_north, lon_west, ref.dlat, ref.dlon,
                     int((~covered).sum()))


def mosaic(index: TileIndex, priority: str = "agree", name: str = "tiles") -> Dem:
    """The merged raster; shared posts must agree unless ``priority == "first"``."""
    if priority not in PRIORITIES:
        raise DemError(f"tile priority must be one of {', '.join(PRIORITIES)}, got {priority!r}")
    heights = np.full(index.shape, np.nan)
    filled = np.zeros(index.shape, bool)
    for t, (r, c) in zip(index.tiles, index.offsets, strict=True):
        win = (slice(r, r + t.shape[0]), slice(c, c + t.shape[1]))
        old, old_filled = heights[win], filled[win]
        if priority == "agree":
            both = old_filled
            same = (old == t.heights) | (np.isnan(old) & np.isnan(t.heights))
            bad = both & ~same
            if bad.any():
                i, j = np.argwhere(bad)[0]
                raise DemError(
                    f"{name}: overlapping tiles disagree at {int(bad.sum())} shared posts, e.g. "
                    f"{t.name} post ({i}, {j}) = {t.heights[i, j]:g} m against "
                    f"{old[i, j]:g} m (use priority 'first' to let the first-named tile win)")
            old[:] = t.heights
        else:
            old[~old_filled] = t.heights[~old_filled]
        old_filled[:] = True
    return Dem(heights, index.lat_north, index.lon_west, index.dlat, index.dlon, name=name)


def open_terrain(path, cache_mb: float | None = None, priority: str = "agree") -> Dem:
    """The terrain at ``path``: one DEM file, a tile directory, or ``"default"``/None."""
    if cache_mb is not None and not cache_mb > 0:
        raise DemError(f"tile cache must be positive, got {cache_mb:g} MiB")
    if path is None or str(path) == "default":
        return Dem.default()
    path = Path(path)
    if path.is_dir():
        return mosaic(index_tiles(path), priority=priority, name=path.name)
    return Dem.from_file(path)


def split_bounds(n: int, parts: int):
    """Post ranges [start, stop) of ``parts`` pieces of ``n`` posts sharing their edge posts."""
    if parts < 1 or parts > n - 1:
        raise DemError(f"cannot split {n} posts into {parts} tiles of at least 2 posts")
    edges = [round(k * (n - 1) / parts) for k in range(parts + 1)]
    return [(edges[k], edges[k + 1] + 1) for k in range(parts)]


def split(dem: Dem, rows: int, cols: int, out_dir) -> list:
    """Write ``dem`` as rows x cols GeoTIFF tiles sharing edge posts; returns the paths."""
    import rasterio
    from rasterio.transform import from_origin

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    dlat_d, dlon_d = math.degrees(dem.dlat), math.degrees(dem.dlon)
    paths = []
    for a, (r0, r1) in enumerate(split_bounds(dem.shape[0], rows)):
        for b, (c0, c1) in enumerate(split_bounds(dem.shape[1], cols)):
            block = dem.heights[r0:r1, c0:c1]
            north = math.degrees(dem.lat_north - r0 * dem.dlat) + dlat_d / 2
            west = math.degrees(dem.lon_west + c0 * dem.dlon) - dlon_d / 2
            path = out_dir / f"tile_r{a}_c{b}.tif"
            with rasterio.open(path, "w", driver="GTiff", height=block.shape[0],
                               width=block.shape[1], count=1, dtype="float64",
                               crs="EPSG:4326", transform=from_origin(west, north, dlon_d, dlat_d),
                               nodata=np.nan) as dst:
                dst.write(block, 1)
            paths.append(path)
    return paths
