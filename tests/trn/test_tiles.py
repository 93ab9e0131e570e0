"""DEM tile directories: split/merge round trip, seams bit for bit, bad tile sets."""

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
def test_split_then_open_is_the_whole_dem(dem, tmp_path, rows, cols):
    paths = tiles.split(dem, rows, cols, tmp_path)
    assert len(paths) == rows * cols
    merged = tiles.open_terrain(tmp_path)
    assert np.array_equal(merged.heights, dem.heights, equal_nan=True)
    assert (merged.lat_north, merged.lon_west, merged.dlat, merged.dlon) == (
        dem.lat_north, dem.lon_west, dem.dlat, dem.dlon)


def test_heights_and_gradients_across_seams_match_bit_for_bit(dem, tmp_path):
    tiles.split(dem, 2, 2, tmp_path)
    merged = tiles.open_terrain(tmp_path)
    rng = np.random.default_rng(0)
    # points straddling the row and column seams (the shared posts)
    (r0, r1), _ = tiles.split_bounds(dem.shape[0], 2)
    seam_lat = dem.lat_north - (r1 - 1) * dem.dlat
    lat = seam_lat + rng.uniform(-2, 2, 500) * dem.dlat
    lon = dem.lon_west + rng.uniform(1, dem.shape[1] - 2, 500) * dem.dlon
    assert np.array_equal(merged.height(lat, lon), dem.height(lat, lon), equal_nan=True)
    for a, b in zip(merged.gradient(lat, lon), dem.gradient(lat, lon), strict=True):
        assert np.array_equal(a, b, equal_nan=True)


def _write(path, block, north_deg, west_deg, d_deg):
    with rasterio.open(path, "w", driver="GTiff", height=block.shape[0], width=block.shape[1],
                       count=1, dtype="float64", crs="EPSG:4326",
                       transform=from_origin(west_deg, north_deg, d_deg, d_deg)) as dst:
        dst.write(block, 1)


def test_empty_directory_is_an_error(tmp_path):
    with pytest.raises(DemError, match="no DEM tiles"):
        tiles.open_terrain(tmp_path)


def test_corrupt_tile_is_an_error(dem, tmp_path):
    tiles.split(dem, 2, 2, tmp_path)
    (tmp_path / "tile_r0_c1.tif").write_bytes(b"not a tiff")
    with pytest.raises(DemError, match="not a readable DEM"):
        tiles.open_terrain(tmp_path)


def test_overlap_that_disagrees_is_an_error_unless_priority_given(tmp_path):
    d = 1 / 1200
    a = np.full((5, 5), 100.0)
    b = np.full((5, 5), 100.0)
    b[:, 0] = 101.0  # b's west column is a's east column, one metre off
    _write(tmp_path / "a.tif", a, 36.0 + d / 2, -84.0 - d / 2, d)
    _write(tmp_path / "b.tif", b, 36.0 + d / 2, -84.0 + 4 * d - d / 2, d)
    with pytest.raises(DemError, match="disagree at 5 shared posts"):
        tiles.open_terrain(tmp_path)
    merged = tiles.open_terrain(tmp_path, priority="first")
    assert merged.shape == (5, 9)
    assert np.all(merged.heights[:, 4] == 100.0)  # a.tif sorts first and wins


def test_gap_between_tiles_is_void_not_zero(tmp_path):
    d = 1 / 1200
    _write(tmp_path / "a.tif", np.full((5, 5), 100.0), 36.0 + d / 2, -84.0 - d / 2, d)
    _write(tmp_path / "b.tif", np.full((5, 5), 200.0), 36.0 + d / 2, -84.0 + 7 * d - d / 2, d)
    index = tiles.index_tiles(tmp_path)
    assert index.gap_posts == 5 * 2
    merged = tiles.mosaic(index)
    assert np.all(np.isnan(merged.heights[:, 5:7]))
    lat = math.radians(36.0 - 2 * d)
    assert math.isnan(merged.height(lat, math.radians(-84.0 + 5.5 * d)))
    assert merged.height(lat, math.radians(-84.0 + 2 * d)) == pytest.approx(100.0, abs=1e-9)


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
    with pytest.raises(DemError, match="not on the post grid"):
        tiles.open_terrain(tmp_path)


def test_split_rejects_too_many_parts():
    with pytest.raises(DemError, match="cannot split"):
        tiles.split_bounds(3, 3)
