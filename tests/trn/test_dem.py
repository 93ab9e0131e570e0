"""DEM loading and queries: the embedded real DEM, GeoTIFF through rasterio, voids, off-map,
bad files."""

import math

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from navgate.trn.dem import Dem, DemError


def write_geotiff(path, heights, *, west=-84.0, north=36.5, res=1 / 1200, nodata=-9999.0,
                  crs="EPSG:4326", dtype="float32"):
    heights = np.asarray(heights)
    with rasterio.open(path, "w", driver="GTiff", width=heights.shape[1],
                       height=heights.shape[0], count=1, dtype=dtype, crs=crs,
                       transform=from_origin(west, north, res, res), nodata=nodata) as dst:
        dst.write(heights.astype(dtype), 1)
    return path


def test_embedded_default_dem_is_the_real_jacksboro_tile():
    d = Dem.default()
    assert d.shape == (344, 403)
    sn, se = d.post_spacing_m()
    assert 92 < sn < 93 and 74 < se < 75.5  # 3 arc-seconds at 36.6 N
    assert np.nanmin(d.heights) == 236 and np.nanmax(d.heights) == 1076
    assert d.void_fraction() == 0.0


def test_bilinear_is_exact_at_posts_and_linear_between(tmp_path):
    h = np.arange(20, dtype=float).reshape(4, 5) * 10.0
    d = Dem.from_file(write_geotiff(tmp_path / "ramp.tif", h))
    for i, j in [(0, 0), (2, 3), (3, 4)]:
        assert d.height(d.lat_north - i * d.dlat, d.lon_west + j * d.dlon) == pytest.approx(h[i, j])
    # a plane z = 50 i + 10 j is reproduced exactly anywhere inside
    fi, fj = 1.25, 2.6
    got = d.height(d.lat_north - fi * d.dlat, d.lon_west + fj * d.dlon)
    assert got == pytest.approx(50 * fi + 10 * fj, abs=1e-9)


def test_voids_and_off_map_give_nan(tmp_path):
    h = np.full((6, 6), 100.0)
    h[2, 2] = -9999.0
    d = Dem.from_file(write_geotiff(tmp_path / "void.tif", h))
    assert d.void_fraction() == pytest.approx(1 / 36)
    assert math.isnan(d.height(d.lat_north - 2.5 * d.dlat, d.lon_west + 2.5 * d.dlon))
    assert d.height(d.lat_north - 4.5 * d.dlat, d.lon_west + 4.5 * d.dlon) == 100.0
    assert math.isnan(d.height(d.lat_north + d.dlat, d.lon_west))  # north of the map
    assert math.isnan(d.height(d.lat_north, d.lon_east + 1e-9))


def test_srtm_void_marker_and_south_up_raster(tmp_path):
    h = np.array([[10, 20, 30], [40, -32768, 60], [70, 80, 90]], dtype=np.int16)
    d = Dem.from_file(write_geotiff(tmp_path / "srtm.tif", h, nodata=None, dtype="int16"))
    assert np.isnan(d.heights[1, 1]) and d.heights[0, 0] == 10


def test_gradient_of_a_plane(tmp_path):
    res = 1 / 1200
    h = np.add.outer(-np.arange(30) * 5.0, np.arange(30) * 2.0)  # rises 5 m/post north
    d = Dem.from_file(write_geotiff(tmp_path / "plane.tif", h, res=res))
    sn, se = d.post_spacing_m()
    gn, ge = d.gradient(np.array([d.center[0]]), np.array([d.center[1]]))
    assert gn[0] == pytest.approx(5.0 / sn, rel=1e-3) and ge[0] == pytest.approx(2.0 / se, rel=1e-3)


def test_bad_files_give_clear_errors(tmp_path):
    with pytest.raises(DemError, match="not found"):
        Dem.from_file(tmp_path / "missing.tif")
    junk = tmp_path / "junk.tif"
    junk.write_bytes(b"this is not a raster")
    with pytest.raises(DemError, match="not a readable DEM"):
        Dem.from_file(junk)
    projected = write_geotiff(tmp_path / "utm.tif", np.ones((5, 5)), west=500000, north=4000000,
                              res=30.0, crs="EPSG:32616")
    with pytest.raises(DemError, match="geographic"):
        Dem.from_file(projected)
    all_void = write_geotiff(tmp_path / "void.tif", np.full((4, 4), -9999.0))
    with pytest.raises(DemError, match="no valid heights"):
        Dem.from_file(all_void)
    with pytest.raises(DemError, match="directory"):
        Dem.from_file(tmp_path)


def test_shared_geotiff_dem_loads(shared_data):
    path = shared_data / "pysheds_dem.tif"
    if not path.exists():
        pytest.skip("pysheds_dem.tif not present")
    d = Dem.from_file(path)
    assert d.shape == (359, 367)
    assert 140 < np.nanmin(d.heights) and np.nanmax(d.heights) < 300


@pytest.mark.parametrize("driver, name, posts", [("DTED", "n36w084.dt0", 121),
                                                 ("SRTMHGT", "N36W084.hgt", 1201)])
def test_dted_and_srtm_hgt_load_through_gdal(tmp_path, driver, name, posts):
    """Write a 1 x 1 deg cell with GDAL's own DTED / SRTM writers, read it back as a Dem."""
    import rasterio.shutil
    from rasterio.io import MemoryFile

    h = np.random.default_rng(0).integers(100, 500, (posts, posts)).astype("int16")
    res = 1.0 / (posts - 1)
    transform = from_origin(-84.0 - res / 2, 37.0 + res / 2, res, res)
    profile = dict(driver="GTiff", width=posts, height=posts, count=1, dtype="int16",
                   crs="EPSG:4326", transform=transform)
    with MemoryFile() as mem:
        with mem.open(**profile) as src:
            src.write(h, 1)
        with mem.open() as src:
            rasterio.shutil.copy(src, tmp_path / name, driver=driver)
    d = Dem.from_file(tmp_path / name)
    assert d.shape == (posts, posts)
    assert np.array_equal(d.heights, h.astype(float))
    # post (0, 0) sits on the cell's north-west corner, 37 N 84 W
    assert math.degrees(d.lat_north) == pytest.approx(37.0, abs=1e-9)
    assert math.degrees(d.lon_west) == pytest.approx(-84.0, abs=1e-9)
    # the centre post; the geotransform in degrees -> radians leaves ~1e-9 post of rounding
    centre = h[(posts - 1) // 2, (posts - 1) // 2]
    assert d.height(math.radians(36.5), math.radians(-83.5)) == pytest.approx(centre, abs=1e-6)
