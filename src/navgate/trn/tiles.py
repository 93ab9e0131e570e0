"""A directory of DEM tiles seen as one terrain surface: the Pi's DTED cache of seed 000.

Seed 000 ("System Overview") gives the Raspberry Pi a DTED cache on its SD card: terrain comes
in tiles (DTED level 0/1/2 one-degree cells, SRTM ``.hgt`` files, GeoTIFF), far more of them
than fit in memory. :class:`TileStore` indexes a directory of such tiles from their headers at
start-up, reads a tile only when a query needs it, and keeps the tiles it read in an LRU
cache under a byte cap. To its users (the correlators, the flight's ranger, the route planner)
it is one grid, exactly as if the tiles had been merged into one raster:

- The tiles must lie on one lattice: the same post spacing, origins a whole number of posts
  apart. The merged grid's origin is the north-west tile's, computed the way
  :meth:`navgate.trn.dem.Dem.from_file` computes it, so a tile set cut from a DEM by
  ``navgate tiles split`` has that DEM's origin to the last bit.
- Heights and gradients are bit-identical to the merged raster's, seams included: every query
  runs the same bilinear kernel (:func:`navgate.trn.dem.bilinear_at`), whose arithmetic depends
  on the merged grid only, on a window assembled from the tiles around the query.
- Posts held by two tiles (DTED and SRTM cells share their edge rows and columns) must agree:
  ``priority="check"`` (the default) raises :class:`~navgate.trn.dem.DemError` naming both
  tiles where they differ; ``"first"`` / ``"last"`` let the tile first / last in file-name
  order win, and count the posts where it mattered.
- Voids (a tile's nodata, the SRTM void -32768) and gaps (posts no tile covers) are NaN,
  never zero: the correlators treat NaN as "no terrain here" and TRN pauses. Queries that hit
  a gap are counted. Tiles of different post spacing, rotated or projected tiles, unreadable
  tiles, and a directory without tiles are refused with one clear error.

Bytes: a tile costs ``rows x cols x 8`` bytes in the cache (float64 heights). With a cap, the
least recently used tiles are dropped once the cache holds more than the cap (the tiles a
single window needs are kept while it is assembled, so the cap is a target, not a refusal).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from navgate.trn.dem import (
    MAX_TERRAIN_M,
    MIN_TERRAIN_M,
    Dem,
    DemError,
    GridWindow,
    bilinear_many_at,
    read_header,
    read_raster,
    terrain_gradient,
)

#: file endings indexed as tiles (case-insensitive)
TILE_SUFFIXES = (".tif", ".tiff", ".dt0", ".dt1", ".dt2", ".hgt")
PRIORITIES = ("check", "first", "last")
#: the fewest post intervals a side of a tile made by split_dem (smaller tiles only cost I/O)
MIN_TILE_CELLS = 8
#: the most posts per side of the blocks that point queries are grouped into (smaller for
#: small tiles, so that one block's window touches at most the four tiles around a corner)
_BLOCK = 256
#: how far (in posts) a tile origin may sit from the lattice and still count as on it
_ALIGN_TOL = 1e-6


@dataclass(frozen=True)
class TileInfo:
    """One tile's place in the merged grid: posts ``row0 .. row0 + rows - 1`` etc."""

    path: Path
    row0: int
    col0: int
    rows: int
    cols: int

    @property
    def nbytes(self) -> int:
        return self.rows * self.cols * 8

    def overlaps(self, r_lo: int, r_hi: int, c_lo: int, c_hi: int) -> bool:
        """Does the tile hold any post of rows [r_lo, r_hi) x cols [c_lo, c_hi)?"""
        return (self.row0 < r_hi and r_lo < self.row0 + self.rows
                and self.col0 < c_hi and c_lo < self.col0 + self.cols)


def _how_they_differ(old: np.ndarray, new: np.ndarray) -> str:
    """What differs at shared posts that disagree: heights (the largest difference) and
    posts void (NaN) in one tile but not in the other."""
    both = np.isfinite(old) & np.isfinite(new)
    parts = []
    if both.any():
        parts.append(f"largest height difference {np.max(np.abs(old[both] - new[both])):.4g} m")
    void = int((~both).sum())
    if void:
        parts.append(f"{void} of them void in one tile and not in the other")
    return "; ".join(parts)


def tile_paths(directory: Path) -> list[Path]:
    return sorted(p for p in directory.iterdir()
                  if p.is_file() and p.suffix.lower() in TILE_SUFFIXES)


class TileStore:
    """A tile directory as one terrain grid (the interface of :class:`~navgate.trn.dem.Dem`)."""

    def __init__(self, directory, cache_mb: float | None = None, priority: str = "check"):
        directory = Path(directory)
        if directory.exists() and not directory.is_dir():
            raise DemError(f"not a tile directory: {directory} (a file, a device or a FIFO)")
        if not directory.is_dir():
            raise DemError(f"tile directory not found: {directory}")
        if priority not in PRIORITIES:
            raise ValueError(f"priority must be one of {PRIORITIES}, got {priority!r}")
        if cache_mb is not None and not (math.isfinite(cache_mb) and cache_mb > 0):
            raise ValueError(f"cache_mb must be a positive number of MiB, got {cache_mb!r}")
        paths = tile_paths(directory)
        if not paths:
            raise DemError(f"{directory}: no DEM tiles ({', '.join(TILE_SUFFIXES)}) in it")
        headers = [(p, read_header(p)) for p in paths]
        self.directory = directory
        self.name = directory.name or str(directory)
        self.priority = priority
        self.cache_bytes = None if cache_mb is None else int(cache_mb * 2**20)
        self._index(headers)
        self._cache: OrderedDict[Path, np.ndarray] = OrderedDict()
        self.loads = self.evictions = self.hits = 0
        self.peak_bytes = 0
        self.gap_queries = 0  #: point queries that fell on posts no tile covers
        self.priority_posts = 0  #: overlapping posts that disagreed and were settled by priority
        self._scan: dict | None = None

    # -- index ------------------------------------------------------------------------------
    def _index(self, headers):
        p0, h0 = headers[0]
        for p, h in headers[1:]:
            for what, a, b in (("latitude", h.dlat, h0.dlat), ("longitude", h.dlon, h0.dlon)):
                if abs(a - b) > 1e-9 * b:
                    raise DemError(
                        f"tiles of different post spacing: {p.name} has "
                        f"{math.degrees(a) * 3600:.6g} arc-seconds in {what}, {p0.name} "
                        f"{math.degrees(b) * 3600:.6g}; one store holds one spacing (resample "
                        "or keep them in separate directories)")
        self.dlat, self.dlon = h0.dlat, h0.dlon
        north = max(headers, key=lambda ph: ph[1].lat_north)[1]
        west = min(headers, key=lambda ph: ph[1].lon_west)[1]
        self.lat_north, self.lon_west = north.lat_north, west.lon_west
        self.edges_deg = None
        if north.edges_deg is not None and west.edges_deg is not None:
            self.edges_deg = (west.edges_deg[0], north.edges_deg[1], north.edges_deg[2],
                              north.edges_deg[3])
        tiles = []
        for p, h in headers:
            fr = (self.lat_north - h.lat_north) / self.dlat
            fc = (h.lon_west - self.lon_west) / self.dlon
            r0, c0 = round(fr), round(fc)
            if abs(fr - r0) > _ALIGN_TOL or abs(fc - c0) > _ALIGN_TOL:
                raise DemError(f"{p.name} is not on the posts of the other tiles (it is "
                               f"{fr - r0:+.3g} rows, {fc - c0:+.3g} columns off the lattice)")
            tiles.append(TileInfo(p, int(r0), int(c0), h.rows, h.cols))
        self.tiles = tiles
        self.nrow = max(t.row0 + t.rows for t in tiles)
        self.ncol = max(t.col0 + t.cols for t in tiles)
        if self.nrow < 2 or self.ncol < 2:
            raise DemError(f"{self.directory}: the tiles hold fewer than 2 x 2 posts")
        self.gap_posts = self._uncovered_posts()
        smallest = min(min(t.rows, t.cols) for t in tiles)
        self.block = int(min(_BLOCK, max(16, smallest - 3)))
        self.overlapping_pairs = [
            (a.path.name, b.path.name) for k, a in enumerate(tiles) for b in tiles[k + 1:]
            if a.overlaps(b.row0, b.row0 + b.rows, b.col0, b.col0 + b.cols)]

    def _uncovered_posts(self) -> int:
        """Posts of the bounding grid that no tile covers (on the grid compressed to the
        tiles' edges, so it costs nothing however large the tiles)."""
        rows = sorted({0, self.nrow} | {t.row0 for t in self.tiles}
                      | {t.row0 + t.rows for t in self.tiles})
        cols = sorted({0, self.ncol} | {t.col0 for t in self.tiles}
                      | {t.col0 + t.cols for t in self.tiles})
        covered = np.zeros((len(rows) - 1, len(cols) - 1), bool)
        for t in self.tiles:
            i0, i1 = rows.index(t.row0), rows.index(t.row0 + t.rows)
            j0, j1 = cols.index(t.col0), cols.index(t.col0 + t.cols)
            covered[i0:i1, j0:j1] = True
        sizes = np.outer(np.diff(rows), np.diff(cols))
        return int(sizes[~covered].sum())

    # -- the cache --------------------------------------------------------------------------
    def _tile(self, tile: TileInfo, keep: set) -> np.ndarray:
        data = self._cache.get(tile.path)
        if data is not None:
            self._cache.move_to_end(tile.path)
            self.hits += 1
            return data
        data, header = read_raster(tile.path)
        if data.shape != (tile.rows, tile.cols):
            raise DemError(f"{tile.path.name}: read {data.shape} posts, its header said "
                           f"{(tile.rows, tile.cols)}")
        finite = data[np.isfinite(data)]
        if finite.size and (finite.max() > MAX_TERRAIN_M or finite.min() < MIN_TERRAIN_M):
            raise DemError(f"{tile.path.name}: heights from {finite.min():.4g} to "
                           f"{finite.max():.4g} are not terrain heights in metres")
        self.loads += 1
        self._cache[tile.path] = data
        self.peak_bytes = max(self.peak_bytes, self.cached_bytes)
        self._evict(keep)
        return data

    def _evict(self, keep: set):
        if self.cache_bytes is None:
            return
        for path in list(self._cache):
            if self.cached_bytes <= self.cache_bytes:
                break
            if path not in keep:
                del self._cache[path]
                self.evictions += 1

    @property
    def cached_bytes(self) -> int:
        return sum(a.nbytes for a in self._cache.values())

    def stats(self) -> dict:
        """Counters of the cache and of the queries, for summaries and status requests."""
        return {"tiles": len(self.tiles), "tile_loads": self.loads,
                "tile_evictions": self.evictions, "tile_hits": self.hits,
                "cache_cap_bytes": self.cache_bytes, "cached_bytes": self.cached_bytes,
                "peak_cached_bytes": self.peak_bytes, "gap_posts": self.gap_posts,
                "gap_queries": self.gap_queries, "priority_posts": self.priority_posts}

    # -- assembling windows -----------------------------------------------------------------
    def assemble(self, r_lo: int, r_hi: int, c_lo: int, c_hi: int) -> np.ndarray:
        """Posts rows [r_lo, r_hi) x cols [c_lo, c_hi) of the merged grid (NaN: void or gap)."""
        r_lo, c_lo = max(r_lo, 0), max(c_lo, 0)
        r_hi, c_hi = min(r_hi, self.nrow), min(c_hi, self.ncol)
        out = np.full((max(r_hi - r_lo, 0), max(c_hi - c_lo, 0)), np.nan)
        if out.size == 0:
            return out
        written = np.zeros(out.shape, bool)
        tiles = [t for t in self.tiles if t.overlaps(r_lo, r_hi, c_lo, c_hi)]
        if self.priority == "first":
            tiles = tiles[::-1]  # the first in name order is written last and wins
        keep = {t.path for t in tiles}
        for t in tiles:
            data = self._tile(t, keep)
            a0, a1 = max(r_lo, t.row0), min(r_hi, t.row0 + t.rows)
            b0, b1 = max(c_lo, t.col0), min(c_hi, t.col0 + t.cols)
            src = data[a0 - t.row0:a1 - t.row0, b0 - t.col0:b1 - t.col0]
            dst = (slice(a0 - r_lo, a1 - r_lo), slice(b0 - c_lo, b1 - c_lo))
            seen = written[dst]
            if seen.any():
                old = out[dst][seen]
                new = src[seen]
                differ = ~((old == new) | (np.isnan(old) & np.isnan(new)))
                if differ.any():
                    if self.priority == "check":
                        others = [o.path.name for o in tiles if o is not t
                                  and o.overlaps(a0, a1, b0, b1)]
                        raise DemError(
                            f"overlapping tiles disagree: {t.path.name} and "
                            f"{', '.join(others)} differ at {int(differ.sum())} shared posts "
                            f"({_how_they_differ(old[differ], new[differ])}); choose a "
                            "winner with --tile-priority first|last")
                    self.priority_posts += int(differ.sum())
            out[dst] = src
            written[dst] = True
        self._evict(set())
        return out

    def _rows_cols(self, lat_lo, lat_hi, lon_lo, lon_hi):
        r_lo = int(math.floor((self.lat_north - lat_hi) / self.dlat)) - 1
        r_hi = int(math.ceil((self.lat_north - lat_lo) / self.dlat)) + 2
        c_lo = int(math.floor((lon_lo - self.lon_west) / self.dlon)) - 1
        c_hi = int(math.ceil((lon_hi - self.lon_west) / self.dlon)) + 2
        return r_lo, r_hi, c_lo, c_hi

    def window(self, lat_lo, lat_hi, lon_lo, lon_hi) -> GridWindow:
        """The merged grid's posts around the box (rad), one post of margin all round."""
        r_lo, r_hi, c_lo, c_hi = self._rows_cols(lat_lo, lat_hi, lon_lo, lon_hi)
        r_lo, c_lo = max(r_lo, 0), max(c_lo, 0)
        return GridWindow(self.assemble(r_lo, r_hi, c_lo, c_hi), r_lo, c_lo, self.nrow,
                          self.ncol, self.lat_north, self.lon_west, self.dlat, self.dlon)

    # -- queries (the Dem interface) --------------------------------------------------------
    def height(self, lat, lon):
        """Bilinear height(s) (m) at lat, lon (rad): the merged raster's, bit for bit."""
        lat_a = np.atleast_1d(np.asarray(lat, float)).ravel()
        lon_a = np.atleast_1d(np.asarray(lon, float)).ravel()
        lat_a, lon_a = np.broadcast_arrays(lat_a, lon_a)
        out = np.full(lat_a.shape, np.nan)
        fi = (self.lat_north - lat_a) / self.dlat
        fj = (lon_a - self.lon_west) / self.dlon
        inside = (fi > -1.0) & (fj > -1.0) & (fi < self.nrow) & (fj < self.ncol)
        size = self.block
        bi = np.where(inside, np.floor(np.clip(fi, 0, self.nrow - 1) / size), -1)
        bj = np.where(inside, np.floor(np.clip(fj, 0, self.ncol - 1) / size), -1)
        for block in np.unique(np.stack([bi, bj], axis=1)[inside], axis=0):
            k = np.flatnonzero(inside & (bi == block[0]) & (bj == block[1]))
            r_lo, c_lo = int(block[0]) * size - 1, int(block[1]) * size - 1
            r_lo, c_lo = max(r_lo, 0), max(c_lo, 0)
            hw = self.assemble(r_lo, int(block[0] + 1) * size + 2, c_lo,
                               int(block[1] + 1) * size + 2)
            out[k] = bilinear_many_at(hw, r_lo, c_lo, self.nrow, self.ncol, self.lat_north,
                                      self.lon_west, self.dlat, self.dlon,
                                      np.ascontiguousarray(lat_a[k]),
                                      np.ascontiguousarray(lon_a[k]))
        if self.gap_posts:
            self.gap_queries += int(np.count_nonzero(inside & ~np.isfinite(out)
                                                     & self._in_gap(fi, fj)))
        if np.ndim(lat) == 0 and np.ndim(lon) == 0:
            return float(out[0])
        return out.reshape(np.broadcast_shapes(np.shape(lat), np.shape(lon)))

    def _in_gap(self, fi, fj):
        i = np.clip(np.floor(fi), 0, self.nrow - 1)
        j = np.clip(np.floor(fj), 0, self.ncol - 1)
        held = np.zeros(i.shape, bool)
        for t in self.tiles:
            held |= ((i >= t.row0) & (i < t.row0 + t.rows - 1)
                     & (j >= t.col0) & (j < t.col0 + t.cols - 1))
        return ~held

    def gradient(self, lat, lon, step_m: float | None = None):
        return terrain_gradient(self, lat, lon, step_m)

    # -- geometry (the Dem interface) -------------------------------------------------------
    @property
    def shape(self):
        return (self.nrow, self.ncol)

    lat_south = Dem.lat_south
    lon_east = Dem.lon_east
    center = Dem.center
    post_spacing_m = Dem.post_spacing_m

    @property
    def size_bytes(self) -> int:
        """What the whole tile set would take in memory (float64)."""
        return sum(t.nbytes for t in self.tiles)

    def scan(self) -> dict:
        """One pass over the tiles, one or two at a time (the cache cap holds): the rows and
        columns that hold data, the voids (a post shared by tiles counted once), the height
        range, and every overlap compared under the priority rule. Done once, on first need."""
        if self._scan is None:
            valid_rows = np.zeros(self.nrow, bool)
            valid_cols = np.zeros(self.ncol, bool)
            voids, lo, hi = 0, math.inf, -math.inf
            for k, t in enumerate(self.tiles):
                data = self._tile(t, {t.path})
                ok = np.isfinite(data)
                valid_rows[t.row0:t.row0 + t.rows] |= ok.any(axis=1)
                valid_cols[t.col0:t.col0 + t.cols] |= ok.any(axis=0)
                if ok.any():
                    lo, hi = min(lo, float(data[ok].min())), max(hi, float(data[ok].max()))
                first = np.ones(data.shape, bool)  # posts no earlier tile holds
                for other in self.tiles[:k]:
                    a0, a1 = max(t.row0, other.row0), min(t.row0 + t.rows,
                                                          other.row0 + other.rows)
                    b0, b1 = max(t.col0, other.col0), min(t.col0 + t.cols,
                                                          other.col0 + other.cols)
                    if a0 < a1 and b0 < b1:
                        first[a0 - t.row0:a1 - t.row0, b0 - t.col0:b1 - t.col0] = False
                        self.assemble(a0, a1, b0, b1)  # compares the shared posts
                voids += int(np.count_nonzero(first & ~ok))
            if not valid_rows.any():
                raise DemError(f"{self.directory}: the tiles hold no valid heights (all voids)")
            self._scan = {"valid_rows": np.flatnonzero(valid_rows),
                          "valid_cols": np.flatnonzero(valid_cols),
                          "void_posts": voids, "min_m": lo, "max_m": hi}
        return self._scan

    def valid_bounds(self):
        """(lat_south, lat_north, lon_west, lon_east) of the rows/columns that hold data."""
        s = self.scan()
        rows, cols = s["valid_rows"], s["valid_cols"]
        return (self.lat_north - rows[-1] * self.dlat, self.lat_north - rows[0] * self.dlat,
                self.lon_west + cols[0] * self.dlon, self.lon_west + cols[-1] * self.dlon)

    def void_fraction(self) -> float:
        """Posts without a height (voids and gaps) over the merged grid's posts."""
        s = self.scan()
        return (s["void_posts"] + self.gap_posts) / (self.nrow * self.ncol)

    def overview(self, max_posts: int = 1500) -> tuple[np.ndarray, int]:
        """The merged heights decimated to at most ``max_posts`` a side (for plots), read one
        tile at a time so the cache cap holds."""
        step = max(1, math.ceil(max(self.nrow, self.ncol) / max_posts))
        out = np.full((-(-self.nrow // step), -(-self.ncol // step)), np.nan)
        for t in self.tiles:
            data = self._tile(t, {t.path})
            rows = np.arange(t.row0, t.row0 + t.rows)
            cols = np.arange(t.col0, t.col0 + t.cols)
            rs, cs = rows % step == 0, cols % step == 0
            out[np.ix_(rows[rs] // step, cols[cs] // step)] = data[np.ix_(rs, cs)]
        self._evict(set())
        return out, step

    def hillshade(self, azimuth_deg=315.0, altitude_deg=45.0):
        heights, step = self.overview()
        return Dem(heights if np.isfinite(heights).any() else np.zeros((2, 2)),
                   self.lat_north, self.lon_west, self.dlat * step, self.dlon * step
                   ).hillshade(azimuth_deg, altitude_deg)

    @property
    def heights(self) -> np.ndarray:
        """The merged heights for plotting (decimated when the mosaic is large)."""
        return self.overview()[0]


def load_terrain(path=None, cache_mb: float | None = None, priority: str = "check"):
    """The terrain for a flight or a TRN service: the embedded DEM (``None``), one DEM file,
    or a directory of tiles (:class:`TileStore`)."""
    if path is None:
        return Dem.default()
    path = Path(path)
    if path.is_dir():
        return TileStore(path, cache_mb=cache_mb, priority=priority)
    return Dem.from_file(path)


def split_dem(dem: Dem, rows: int, cols: int, out_dir: Path) -> list[Path]:
    """Cut ``dem`` into ``rows`` x ``cols`` GeoTIFF tiles that share their edge posts (as DTED
    and SRTM cells do), on exactly the DEM's own lattice; returns the files written."""
    from rasterio.io import MemoryFile
    from rasterio.transform import Affine

    nrow, ncol = dem.shape
    if rows < 1 or cols < 1:
        raise ValueError(f"tile counts must be at least 1, got {rows} x {cols}")
    if (nrow - 1) // rows < MIN_TILE_CELLS or (ncol - 1) // cols < MIN_TILE_CELLS:
        raise ValueError(f"a {nrow} x {ncol}-post DEM cannot be cut into {rows} x {cols} "
                         f"tiles of at least {MIN_TILE_CELLS + 1} x {MIN_TILE_CELLS + 1} posts")
    if dem.edges_deg is not None:
        west, north, dlon, dlat = dem.edges_deg
    else:
        dlat, dlon = math.degrees(dem.dlat), math.degrees(dem.dlon)
        north = math.degrees(dem.lat_north) + dlat / 2
        west = math.degrees(dem.lon_west) - dlon / 2
    r_edges = np.linspace(0, nrow - 1, rows + 1).round().astype(int)
    c_edges = np.linspace(0, ncol - 1, cols + 1).round().astype(int)
    width = len(str(max(rows, cols) - 1))
    written = []
    for a in range(rows):
        for b in range(cols):
            r0, r1 = r_edges[a], r_edges[a + 1] + 1
            c0, c1 = c_edges[b], c_edges[b + 1] + 1
            block = dem.heights[r0:r1, c0:c1]
            path = out_dir / f"tile_r{a:0{width}d}_c{b:0{width}d}.tif"
            transform = Affine(dlon, 0.0, west + c0 * dlon if c0 else west,
                               0.0, -dlat, north - r0 * dlat if r0 else north)
            # GDAL encodes the tile in memory and Python writes the bytes: GDAL's own file
            # writer only logs a failed write (a full disk) and carries on, this raises it
            with MemoryFile() as memory:
                with memory.open(driver="GTiff", height=block.shape[0], width=block.shape[1],
                                 count=1, dtype="float64", crs="EPSG:4326",
                                 transform=transform, nodata=np.nan) as dst:
                    dst.write(block, 1)
                path.write_bytes(memory.read())
            written.append(path)
    return written
