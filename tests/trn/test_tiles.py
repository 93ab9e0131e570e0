"""DEM tile directories (navgate.trn.tiles): split/load round trip, seams bit for bit against
the whole DEM, the LRU cap, and bad tile sets."""

import math

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from navgate.trn import tiles
from navgate.trn.dem import Dem, DemError


@pytest.fixture(scope="module")
def dem():
    return Dem.default()


@pytest.mark.parametrize("rows,cols", [(2, 2), (3, 3), (1, 4)])
def test_heights_and_gradients_across_seams_match_the_whole_dem(dem, tmp_path, rows, cols):
    paths = tiles.split_dem(dem, rows, cols, tmp_path)
    assert len(paths) == rows * cols
    store = tiles.open_terrain(tmp_path)
    assert store.shape == dem.shape
    rng = np.random.default_rng(0)
    lat = dem.lat_north - rng.uniform(0, dem.shape[0] - 1, 2000) * dem.dlat
    lon = dem.lon_west + rng.uniform(0, dem.shape[1] - 1, 2000) * dem.dlon
    assert np.array_equal(store.height(lat, lon), dem.height(lat, lon), equal_nan=True)
    for a, b in zip(store.gradient(lat, lon), dem.gradient(lat, lon), strict=True):
        assert np.array_equal(a, b, equal_nan=True)


def test_cache_cap_evicts_and_still_matches(dem, tmp_path):
    tiles.split_dem(dem, 3, 3, tmp_path)
    total = sum(p.stat().st_size for p in tmp_path.glob("*.tif"))
    store = tiles.open_terrain(tmp_path, cache_mb=total / 4 / 2**20)
    lat = np.linspace(dem.lat_south, dem.lat_north, 400)
    lon = np.linspace(dem.lon_west, dem.lon_east, 400)
    assert np.array_equal(store.height(lat, lon), dem.height(lat, lon), equal_nan=True)
    stats = store.stats()
    assert stats["tile_evictions"] > 0 and stats["tile_loads"] > len(store.tiles)
    assert isinstance(stats["cached_bytes"], int)
    assert 0 < stats["cached_bytes"] <= stats["peak_cached_bytes"]


def _write(path, block, north_deg, west_deg, d_deg):
    with rasterio.open(path, "w", driver="GTiff", height=block.shape[0], width=block.shape[1],
                       count=1, dtype="float64", crs="EPSG:4326",
                       transform=from_origin(west_deg, north_deg, d_deg, d_deg)) as dst:
        dst.write(block, 1)


def test_empty_directory_is_an_error(tmp_path):
    with pytest.raises(DemError, match="no DEM tiles"):
        tiles.open_terrain(tmp_path)


def test_overlap_that_disagrees_is_an_error_unless_priority_given(tmp_path):
    d = 1 / 1200
    a = np.full((5, 5), 100.0)
    b = np.full((5, 5), 100.0)
    b[:, 0] = 101.0  # b's west column is a's east column, one metre off
    _write(tmp_path / "a.tif", a, 36.0 + d / 2, -84.0 - d / 2, d)
    _write(tmp_path / "b.tif", b, 36.0 + d / 2, -84.0 + 4 * d - d / 2, d)
    with pytest.raises(DemError, match="disagree"):
        tiles.open_terrain(tmp_path).scan()
    store = tiles.open_terrain(tmp_path, priority="first")
    assert store.shape == (5, 9)
    h = store.height(math.radians(36.0 - 2 * d), math.radians(-84.0 + 4 * d))
    assert h in (100.0, 101.0)


def test_gap_between_tiles_is_void_and_counted(tmp_path):
    d = 1 / 1200
    _write(tmp_path / "a.tif", np.full((5, 5), 100.0), 36.0 + d / 2, -84.0 - d / 2, d)
    _write(tmp_path / "b.tif", np.full((5, 5), 200.0), 36.0 + d / 2, -84.0 + 7 * d - d / 2, d)
    store = tiles.open_terrain(tmp_path)
    assert store.stats()["gap_posts"] == 5 * 2
    lat = math.radians(36.0 - 2 * d)
    assert math.isnan(store.height(lat, math.radians(-84.0 + 5.5 * d)))
    assert store.stats()["gap_queries"] >= 1
    assert store.height(lat, math.radians(-84.0 + 2 * d)) == pytest.approx(100.0, abs=1e-9)


def test_mixed_spacing_is_an_error(tmp_path):
    d = 1 / 1200
    _write(tmp_path / "a.tif", np.full((5, 5), 100.0), 36.0, -84.0, d)
    _write(tmp_path / "b.tif", np.full((5, 5), 100.0), 36.0, -83.0, d / 3)
    with pytest.raises(DemError, match="different post spacing"):
        tiles.open_terrain(tmp_path)


def test_misaligned_tile_is_an_error(tmp_path):
    d = 1 / 1200
    _write(tmp_path / "a.tif", np.full((5, 5), 100.0), 36.0, -84.0, d)
    _write(tmp_path / "b.tif", np.full((5, 5), 100.0), 36.0, -84.0 + 4.5 * d, d)
    with pytest.raises(DemError, match="not on the posts"):
        tiles.open_terrain(tmp_path)
