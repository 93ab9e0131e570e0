"""Digital elevation model on a geographic grid: loading, bilinear height, gradients, voids.

A :class:`Dem` holds heights (m, float64, NaN for voids) at posts on a regular latitude /
longitude grid: row 0 is the northern row, column 0 the western column, post (i, j) at
``lat = lat_north - i dlat``, ``lon = lon_west + j dlon`` (post centres: a GeoTIFF's
pixel-is-area transform is shifted by half a pixel; DTED and SRTM .hgt are read by GDAL
with the same convention, so one rule serves all).

Loading: anything GDAL reads, through rasterio (GeoTIFF, DTED .dt0/.dt1/.dt2, SRTM .hgt),
provided the raster is in geographic coordinates (EPSG:4326 or another lat/lon CRS). The
raster's nodata value and the SRTM void marker -32768 become NaN voids. The embedded
default is the real 3 arc-second DEM that matplotlib ships
(``sample_data/jacksboro_fault_dem.npz``: 344 x 403 posts, about 31 x 31 km of the
Jacksboro fault ridge-and-valley terrain in Tennessee).

Bilinear interpolation returns NaN when any of the four surrounding posts is a void or the
point lies outside the grid; callers treat NaN as "no terrain here" (TRN pauses, it never
propagates a NaN into the filter). The kernels are Numba-compiled for the correlator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit

from navgate.nav.earth import radii

SRTM_VOID = -32768


#: plausible terrain heights in metres: Everest 8,849 m; the deepest land depression (Dead Sea
#: shore, -431 m) and bathymetric DEMs (Challenger Deep, -10,935 m) with some margin
MAX_TERRAIN_M = 9000.0
MIN_TERRAIN_M = -11500.0


class DemError(ValueError):
    """A file that cannot serve as a DEM (missing, unreadable, not geographic, empty)."""


@dataclass(frozen=True)
class RasterHeader:
    """Where a geographic raster's posts lie: post-centre origin and spacing (rad), the size,
    and the source's own edges in degrees (west, north, dlon, dlat) for north-up rasters."""

    rows: int
    cols: int
    lat_north: float
    lon_west: float
    dlat: float
    dlon: float
    edges_deg: tuple | None


def _rasterio(path: Path):
    """rasterio, or a one-line :class:`DemError` naming the extra that brings it (a slim
    install, such as the Zybo's PS, flies the embedded DEM without it)."""
    try:
        import rasterio
        import rasterio.errors
    except ImportError as error:
        if (error.name or "rasterio").split(".")[0] != "rasterio":
            raise
        raise DemError(f"reading {path} needs the Python package 'rasterio', not installed: "
                       'pip install "navgate[dem]" (on the Pi: "navgate[pi]")') from None
    return rasterio


def _open_raster(path: Path):
    return _rasterio(path).open(path)


def _header(src, path: Path) -> RasterHeader:
    if src.count < 1:
        raise DemError(f"{path}: raster has no bands")
    crs = src.crs
    if crs is None or not crs.is_geographic:
        raise DemError(f"{path}: DEM must be in geographic (lat/lon) coordinates, got "
                       f"{crs.to_string() if crs else 'no CRS'}")
    t = src.transform
    if t.b != 0 or t.d != 0:
        raise DemError(f"{path}: rotated rasters are not supported")
    dlon, dlat = t.a, -t.e
    if not (dlon > 0 and dlat != 0 and math.isfinite(dlon) and math.isfinite(dlat)):
        raise DemError(f"{path}: post spacing must be positive, got {dlon!r}, {-dlat!r}")
    rows, cols = src.height, src.width
    if dlat < 0:  # south-up raster: flipped to north-up when read
        return RasterHeader(rows, cols, math.radians(t.f - dlat * (rows - 0.5)),
                            math.radians(t.c + dlon / 2), math.radians(-dlat),
                            math.radians(dlon), None)
    return RasterHeader(rows, cols, math.radians(t.f - dlat / 2), math.radians(t.c + dlon / 2),
                        math.radians(dlat), math.radians(dlon), (t.c, t.f, dlon, dlat))


def read_header(path) -> RasterHeader:
    """The header of a geographic raster, without reading its heights (tile indexing)."""
    path = Path(path)
    RasterioIOError = _rasterio(path).errors.RasterioIOError  # noqa: N806

    try:
        with _open_raster(path) as src:
            return _header(src, path)
    except DemError:
        raise
    except (RasterioIOError, OSError, ValueError) as error:
        raise DemError(f"{path}: not a readable DEM ({' '.join(str(error).split())})") from None


def read_raster(path) -> tuple[np.ndarray, RasterHeader]:
    """Heights (float64, north-up, NaN for nodata and the SRTM void) and header of a raster."""
    path = Path(path)
    RasterioIOError = _rasterio(path).errors.RasterioIOError  # noqa: N806

    try:
        with _open_raster(path) as src:
            header = _header(src, path)
            data = src.read(1, masked=True)
            heights = np.ma.filled(data.astype(np.float64), np.nan)
            nodata = src.nodata
    except DemError:
        raise
    except (RasterioIOError, OSError, ValueError) as error:
        raise DemError(f"{path}: not a readable DEM ({' '.join(str(error).split())})") from None
    heights[heights == SRTM_VOID] = np.nan
    if nodata is not None and np.isfinite(nodata):
        heights[heights == nodata] = np.nan
    if header.edges_deg is None:
        heights = heights[::-1]
    return np.ascontiguousarray(heights), header


@njit(cache=True)
def bilinear_at(heights, row0, col0, nrow, ncol, lat_north, lon_west, dlat, dlon, lat, lon):
    """Bilinear height at (lat, lon) in rad on a grid of ``nrow`` x ``ncol`` posts of which
    ``heights`` holds the block starting at post (``row0``, ``col0``); NaN outside the grid,
    next to a void, or where the block does not hold the four posts.

    The arithmetic depends on the whole grid's origin and spacing only, never on the block:
    a height read from a window of a tile mosaic equals, bit for bit, the height read from
    the merged raster (``navgate.trn.tiles``).
    """
    fi = (lat_north - lat) / dlat
    fj = (lon - lon_west) / dlon
    # points within rounding (1e-9 post) of the outer posts count as on the grid
    if fi < 0.0 and fi > -1e-9:
        fi = 0.0
    if fj < 0.0 and fj > -1e-9:
        fj = 0.0
    if fi > nrow - 1 and fi < nrow - 1 + 1e-9:
        fi = nrow - 1.0
    if fj > ncol - 1 and fj < ncol - 1 + 1e-9:
        fj = ncol - 1.0
    if not (fi >= 0.0 and fj >= 0.0 and fi <= nrow - 1 and fj <= ncol - 1):
        return math.nan
    i = min(int(fi), nrow - 2)
    j = min(int(fj), ncol - 2)
    u = fi - i
    v = fj - j
    bi = i - row0
    bj = j - col0
    if bi < 0 or bj < 0 or bi + 1 >= heights.shape[0] or bj + 1 >= heights.shape[1]:
        return math.nan
    h00 = heights[bi, bj]
    h01 = heights[bi, bj + 1]
    h10 = heights[bi + 1, bj]
    h11 = heights[bi + 1, bj + 1]
    return (h00 * (1.0 - u) * (1.0 - v) + h01 * (1.0 - u) * v
            + h10 * u * (1.0 - v) + h11 * u * v)


@njit(cache=True)
def bilinear(heights, lat_north, lon_west, dlat, dlon, lat, lon):
    """Bilinear height at (lat, lon) in rad; NaN outside the grid or next to a void."""
    return bilinear_at(heights, 0, 0, heights.shape[0], heights.shape[1], lat_north, lon_west,
                       dlat, dlon, lat, lon)


@njit(cache=True)
def bilinear_many_at(heights, row0, col0, nrow, ncol, lat_north, lon_west, dlat, dlon, lat, lon):
    out = np.empty(lat.shape[0])
    for k in range(lat.shape[0]):
        out[k] = bilinear_at(heights, row0, col0, nrow, ncol, lat_north, lon_west, dlat, dlon,
                             lat[k], lon[k])
    return out


def bilinear_many(heights, lat_north, lon_west, dlat, dlon, lat, lon):
    return bilinear_many_at(heights, 0, 0, heights.shape[0], heights.shape[1], lat_north,
                            lon_west, dlat, dlon, lat, lon)


@dataclass(frozen=True)
class GridWindow:
    """A block of a terrain grid: ``heights`` holds posts ``row0..`` x ``col0..`` of a grid of
    ``nrow`` x ``ncol`` posts with the given origin and spacing (rad). The correlators' kernels
    take :meth:`kernel_args` and index the block with the whole grid's arithmetic."""

    heights: np.ndarray
    row0: int
    col0: int
    nrow: int
    ncol: int
    lat_north: float
    lon_west: float
    dlat: float
    dlon: float

    def kernel_args(self):
        return (self.heights, self.row0, self.col0, self.nrow, self.ncol, self.lat_north,
                self.lon_west, self.dlat, self.dlon)


def window_around(terrain, tangent, pos_n, pos_e, pad_m: float) -> GridWindow:
    """The window of ``terrain`` that holds every point within ``pad_m`` (m) of the NED
    positions ``pos_n``, ``pos_e`` (m) about ``tangent``, plus one post all round."""
    n = np.asarray(pos_n, float)
    e = np.asarray(pos_e, float)
    lat_a, lon_a = tangent.to_geodetic(np.array([n.min() - pad_m, n.max() + pad_m]),
                                       np.array([e.min() - pad_m, e.max() + pad_m]))
    return terrain.window(float(np.min(lat_a)), float(np.max(lat_a)),
                          float(np.min(lon_a)), float(np.max(lon_a)))


@dataclass
class Dem:
    """Heights on a geographic grid (angles stored in rad)."""

    heights: np.ndarray
    lat_north: float
    lon_west: float
    dlat: float
    dlon: float
    name: str = "dem"
    #: the source's own (west edge, north edge, dlon, dlat) in degrees, where it has one:
    #: ``navgate tiles split`` writes tiles on exactly this lattice
    edges_deg: tuple | None = None

    def __post_init__(self):
        h = np.ascontiguousarray(self.heights, dtype=np.float64)
        if h.ndim != 2 or h.shape[0] < 2 or h.shape[1] < 2:
            raise DemError(f"{self.name}: a DEM needs at least 2 x 2 posts, got shape {h.shape}")
        if not (self.dlat > 0 and self.dlon > 0):
            raise DemError(f"{self.name}: post spacing must be positive")
        if not np.any(np.isfinite(h)):
            raise DemError(f"{self.name}: the DEM holds no valid heights (all voids)")
        h[~np.isfinite(h)] = np.nan
        lo, hi = float(np.nanmin(h)), float(np.nanmax(h))
        if hi > MAX_TERRAIN_M or lo < MIN_TERRAIN_M:
            raise DemError(f"{self.name}: heights from {lo:.4g} to {hi:.4g} are not terrain "
                           f"heights in metres (Earth's land surface spans {MIN_TERRAIN_M:g} to "
                           f"{MAX_TERRAIN_M:g} m); the DEM looks scaled (centimetres or "
                           "millimetres?) or is not a DEM")
        self.heights = h

    # -- construction ---------------------------------------------------------------------
    @classmethod
    def default(cls) -> Dem:
        """The embedded real DEM: matplotlib's Jacksboro fault sample (3 arc-second posts)."""
        from matplotlib.cbook import get_sample_data

        data = get_sample_data("jacksboro_fault_dem.npz")
        elevation = np.asarray(data["elevation"], dtype=np.float64)
        dx = float(data["dx"])
        dy = float(data["dy"])
        # xmin/xmax and ymin/ymax are cell edges; "ymin" is the northern edge in this file
        north_edge = max(float(data["ymin"]), float(data["ymax"]))
        west_edge = min(float(data["xmin"]), float(data["xmax"]))
        return cls(elevation, math.radians(north_edge - dy / 2), math.radians(west_edge + dx / 2),
                   math.radians(dy), math.radians(dx), name="jacksboro_fault_dem (matplotlib)",
                   edges_deg=(west_edge, north_edge, dx, dy))

    @classmethod
    def from_file(cls, path) -> Dem:
        """Load a GeoTIFF / DTED / SRTM .hgt (anything GDAL reads) through rasterio."""
        path = Path(path)
        if not path.exists():
            raise DemError(f"DEM file not found: {path}")
        if path.is_dir():
            raise DemError(f"DEM path is a directory, not a file: {path}")
        heights, header = read_raster(path)
        return cls(heights, header.lat_north, header.lon_west, header.dlat, header.dlon,
                   name=path.name, edges_deg=header.edges_deg)

    # -- geometry ---------------------------------------------------------------------------
    @property
    def shape(self):
        return self.heights.shape

    @property
    def lat_south(self) -> float:
        return self.lat_north - (self.shape[0] - 1) * self.dlat

    @property
    def lon_east(self) -> float:
        return self.lon_west + (self.shape[1] - 1) * self.dlon

    @property
    def center(self):
        return 0.5 * (self.lat_north + self.lat_south), 0.5 * (self.lon_west + self.lon_east)

    def post_spacing_m(self):
        """(north, east) post spacing in metres at the DEM's centre latitude."""
        lat, _ = self.center
        rn, re = radii(lat)
        return self.dlat * rn, self.dlon * re * math.cos(lat)

    def valid_bounds(self):
        """(lat_south, lat_north, lon_west, lon_east) of the rows/columns that hold data."""
        valid = np.isfinite(self.heights)
        rows = np.flatnonzero(valid.any(axis=1))
        cols = np.flatnonzero(valid.any(axis=0))
        return (self.lat_north - rows[-1] * self.dlat, self.lat_north - rows[0] * self.dlat,
                self.lon_west + cols[0] * self.dlon, self.lon_west + cols[-1] * self.dlon)

    def void_fraction(self) -> float:
        return float(np.mean(~np.isfinite(self.heights)))

    def window(self, lat_lo=None, lat_hi=None, lon_lo=None, lon_hi=None) -> GridWindow:
        """The grid as one :class:`GridWindow` (a DEM in memory hands out all of itself)."""
        return GridWindow(self.heights, 0, 0, self.shape[0], self.shape[1], self.lat_north,
                          self.lon_west, self.dlat, self.dlon)

    # -- queries --------------------------------------------------------------------------------
    def height(self, lat, lon):
        """Bilinear height(s) (m) at lat, lon (rad); NaN off the map or next to a void."""
        lat_a = np.atleast_1d(np.asarray(lat, float)).ravel()
        lon_a = np.atleast_1d(np.asarray(lon, float)).ravel()
        lat_a, lon_a = np.broadcast_arrays(lat_a, lon_a)
        out = bilinear_many(self.heights, self.lat_north, self.lon_west, self.dlat, self.dlon,
                            np.ascontiguousarray(lat_a), np.ascontiguousarray(lon_a))
        if np.ndim(lat) == 0 and np.ndim(lon) == 0:
            return float(out[0])
        return out.reshape(np.broadcast_shapes(np.shape(lat), np.shape(lon)))

    def gradient(self, lat, lon, step_m: float | None = None):
        """(dh/dnorth, dh/deast) (m/m) by central differences of the bilinear surface."""
        return terrain_gradient(self, lat, lon, step_m)

    def hillshade(self, azimuth_deg=315.0, altitude_deg=45.0):
        """Shaded-relief image (0..1) for plots, voids as NaN."""
        from matplotlib.colors import LightSource

        sn, se = self.post_spacing_m()
        filled = np.where(np.isfinite(self.heights), self.heights, np.nanmean(self.heights))
        ls = LightSource(azdeg=azimuth_deg, altdeg=altitude_deg)
        shade = ls.hillshade(filled, vert_exag=1.0, dx=se, dy=sn)
        shade[~np.isfinite(self.heights)] = np.nan
        return shade


def terrain_gradient(terrain, lat, lon, step_m: float | None = None):
    """(dh/dnorth, dh/deast) (m/m) of any terrain grid (a :class:`Dem` or a tile store) by
    central differences of its bilinear surface; the step defaults to half a post."""
    lat = np.asarray(lat, float)
    lon = np.asarray(lon, float)
    rn, re = radii(float(np.mean(lat)))
    sn, se = terrain.post_spacing_m()
    step = step_m if step_m is not None else 0.5 * min(sn, se)
    dlat = step / rn
    dlon = step / (re * math.cos(float(np.mean(lat))))
    gn = (terrain.height(lat + dlat, lon) - terrain.height(lat - dlat, lon)) / (2 * step)
    ge = (terrain.height(lat, lon + dlon) - terrain.height(lat, lon - dlon)) / (2 * step)
    return gn, ge
