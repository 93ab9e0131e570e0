"""The tile store: a directory of DEM tiles seen as one grid, bit-identical to the merged
raster (seams included), under a cache cap, with gaps, voids, overlaps and bad tiles reported;
``navgate tiles split|info`` and ``navgate fly --dem DIR``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from navgate.trn.dem import Dem, DemError
from navgate.trn.pmf import PointMassCorrelator
from navgate.trn.tiles import TileStore, load_terrain, split_dem


@pytest.fixture(scope="module")
def dem():
    return Dem.default()


@pytest.fixture(scope="module")
def split33(dem, tmp_path_factory):
    out = tmp_path_factory.mktemp("t33")
    split_dem(dem, 3, 3, out)
    return out


def _points(dem, n, seed):
    """Random points over the DEM and a little beyond it, plus every seam post and the
    midpoints of seam cells (where a window built wrongly would show first)."""
    rng = np.random.default_rng(seed)
    lat = rng.uniform(dem.lat_south - 2 * dem.dlat, dem.lat_north + 2 * dem.dlat, n)
    lon = rng.uniform(dem.lon_west - 2 * dem.dlon, dem.lon_east + 2 * dem.dlon, n)
    return lat, lon


@pytest.mark.parametrize("grid", [(1, 1), (2, 2), (3, 3), (2, 5)])
def test_heights_and_gradients_equal_the_merged_raster_bit_for_bit(dem, tmp_path, grid):
    split_dem(dem, *grid, tmp_path)
    store = TileStore(tmp_path, cache_mb=0.2)
    assert store.shape == dem.shape
    assert (store.lat_north, store.lon_west, store.dlat, store.dlon) == (
        dem.lat_north, dem.lon_west, dem.dlat, dem.dlon)
    lat, lon = _points(dem, 20000, seed=sum(grid))
    # seams: the posts tiles share, and points a quarter post either side of them
    r_edges = np.linspace(0, dem.shape[0] - 1, grid[0] + 1).round()
    c_edges = np.linspace(0, dem.shape[1] - 1, grid[1] + 1).round()
    for r in r_edges:
        for off in (-0.25, 0.0, 0.25):
            lat = np.append(lat, np.full(50, dem.lat_north - (r + off) * dem.dlat))
            lon = np.append(lon, np.linspace(dem.lon_west, dem.lon_east, 50))
    for c in c_edges:
        for off in (-0.25, 0.0, 0.25):
            lat = np.append(lat, np.linspace(dem.lat_south, dem.lat_north, 50))
            lon = np.append(lon, np.full(50, dem.lon_west + (c + off) * dem.dlon))
    a, b = dem.height(lat, lon), store.height(lat, lon)
    np.testing.assert_array_equal(a, b)  # NaN off the map on both sides, same bits inside
    assert np.isfinite(a).mean() > 0.9
    for ga, gb in zip(dem.gradient(lat, lon), store.gradient(lat, lon), strict=True):
        np.testing.assert_array_equal(ga, gb)
    assert store.valid_bounds() == dem.valid_bounds()
    assert store.void_fraction() == dem.void_fraction()


def test_cache_stays_under_its_cap_and_counts_loads_and_evictions(dem, split33):
    store = TileStore(split33, cache_mb=0.15)  # one tile is ~0.12 MiB
    lat, lon = _points(dem, 4000, seed=3)
    store.height(lat, lon)
    s = store.stats()
    assert s["tile_loads"] >= 9 and s["tile_evictions"] >= s["tile_loads"] - 1
    assert s["cached_bytes"] <= store.cache_bytes
    assert s["peak_cached_bytes"] <= 4 * max(t.nbytes for t in store.tiles)
    # the same query twice with room for the four tiles around it: the second loads nothing
    store = TileStore(split33, cache_mb=4 * 0.13)
    centre = store.tiles[4]
    la = dem.lat_north - (centre.row0 + 5.5) * dem.dlat
    lo = dem.lon_west + (centre.col0 + 5.5) * dem.dlon
    store.height(la, lo)
    loads = store.loads
    store.height(la, lo)
    assert store.loads == loads and store.hits > 0


def test_pmf_on_tiles_equals_pmf_on_the_merged_dem(dem, split33):
    """The correlator's window kernel reads the tiles through the merged grid's arithmetic."""
    from navgate.nav.earth import LocalTangent
    from navgate.trn.profile import ProfileSnapshot

    tan = LocalTangent(*dem.center, 0.0)
    rng = np.random.default_rng(5)
    n = 120
    pos_n = np.linspace(-3000, 3000, n)
    pos_e = 2500.0 + 0.3 * pos_n  # crosses a tile seam (tiles are ~10 km)
    truth = dem.height(*tan.to_geodetic(pos_n + 40.0, pos_e - 25.0))
    profile = ProfileSnapshot(time=np.arange(n) * 0.5, pos_n=pos_n, pos_e=pos_e,
                              h_terrain=truth + rng.normal(0, 3, n))
    results = []
    for terrain in (dem, TileStore(split33, cache_mb=0.3)):
        pmf = PointMassCorrelator(terrain, tan)
        results.append(pmf.correlate(profile, 80.0, np.diag([80.0**2, 80.0**2])))
    a, b = results
    assert a.accepted and b.accepted, (a.reason, b.reason)
    assert (a.shift_n, a.shift_e, a.fix_n, a.fix_e) == (b.shift_n, b.shift_e, b.fix_n, b.fix_e)
    assert np.array_equal(a.cov, b.cov)
    assert abs(a.shift_n - 40.0) < 30 and abs(a.shift_e + 25.0) < 30  # it found the offset


def _fly(navgate_run, args, out):
    code, _, err = navgate_run(["fly", "--duration", "60", "--quiet", "--out", out, *args])
    assert code == 0, err
    return json.loads((out / "summary.json").read_text()), (out / "trajectory.csv").read_bytes()


def test_flight_over_2x2_and_3x3_tile_sets_equals_the_flight_over_the_dem(tmp_path, navgate_run):
    """tiles split default -> fly --dem DIR: the same trajectory, byte for byte (60 s)."""
    base, base_traj = _fly(navgate_run, [], tmp_path / "whole")
    for grid, cap in (("2x2", "0.4"), ("3x3", "0.3")):
        tiles = tmp_path / f"t{grid}"
        code, _, err = navgate_run(["tiles", "split", "default", "--into", grid, "--out", tiles,
                            "--quiet"])
        assert code == 0, err
        summary, traj = _fly(navgate_run, ["--dem", tiles, "--tile-cache-mb", cap],
                             tmp_path / f"fly{grid}")
        assert traj == base_traj
        for run_name in ("ins_only", "trn_aided"):
            for key, value in base[run_name].items():
                if key != "wall_time_s":
                    assert summary[run_name][key] == value, (grid, run_name, key)
        stats = summary["dem"]["tile_store"]
        assert stats["tiles"] == int(grid[0]) ** 2 and stats["tile_loads"] >= stats["tiles"]
        assert stats["cached_bytes"] <= stats["cache_cap_bytes"]


@pytest.mark.slow
def test_ten_minute_flight_over_tiles_equals_the_flight_over_the_dem(tmp_path, navgate_run):
    code, _, err = navgate_run(["fly", "--quiet", "--out", tmp_path / "whole"])
    assert code == 0, err
    for grid in ("2x2", "3x3"):
        tiles = tmp_path / f"t{grid}"
        assert navgate_run(["tiles", "split", "default", "--into", grid, "--out", tiles])[0] == 0
        code, _, err = navgate_run(["fly", "--quiet", "--dem", tiles, "--out", tmp_path / grid])
        assert code == 0, err
        assert ((tmp_path / grid / "trajectory.csv").read_bytes()
                == (tmp_path / "whole" / "trajectory.csv").read_bytes())


def test_tiles_info_reports_coverage_gaps_and_the_cache_a_route_needs(split33, tmp_path,
                                                                       navgate_run):
    code, out, err = navgate_run(["tiles", "info", split33, "--out", tmp_path / "info"])
    assert code == 0, err
    assert "344 x 403" in out and "3 x 3 arc-s" in out
    info = json.loads((tmp_path / "info" / "tiles.json").read_text())
    assert info["tile_count"] == 9 and info["gap_posts"] == 0 and info["void_posts"] == 0
    assert info["route_cache_bytes"] == 4 * info["largest_tile_bytes"]
    # tiles share their edge posts: a column of tiles adds up to the DEM's rows plus the
    # shared ones, and the file names say where each tile sits
    assert sorted(t["file"] for t in info["tiles"]) == [
        f"tile_r{a}_c{b}.tif" for a in range(3) for b in range(3)]
    assert sum(t["rows"] for t in info["tiles"][::3]) == 344 + 2
    assert sum(t["cols"] for t in info["tiles"][:3]) == 403 + 2
    # a tile set with its centre tile missing: the gap is counted, queries there are NaN
    gap = tmp_path / "gap"
    gap.mkdir()
    for f in split33.glob("*.tif"):
        if f.name != "tile_r1_c1.tif":
            (gap / f.name).write_bytes(f.read_bytes())
    code, out, err = navgate_run(["tiles", "info", gap, "--out", tmp_path / "gapinfo"])
    assert code == 0, err
    info = json.loads((tmp_path / "gapinfo" / "tiles.json").read_text())
    centre = TileStore(split33).tiles[4]
    assert info["gap_posts"] == (centre.rows - 2) * (centre.cols - 2)
    store = TileStore(gap)
    la = store.lat_north - (centre.row0 + centre.rows / 2) * store.dlat
    lo = store.lon_west + (centre.col0 + centre.cols / 2) * store.dlon
    assert math.isnan(store.height(la, lo)) and store.gap_queries == 1


def write_tile(path, heights, west, north, res, nodata=-9999.0):
    with rasterio.open(path, "w", driver="GTiff", width=heights.shape[1],
                       height=heights.shape[0], count=1, dtype="float32", crs="EPSG:4326",
                       transform=from_origin(west, north, res, res), nodata=nodata) as dst:
        dst.write(heights.astype("float32"), 1)


def test_overlapping_tiles_that_disagree_are_refused_or_settled_by_priority(tmp_path):
    res = 1 / 1200
    h = np.arange(100, dtype=float).reshape(10, 10) + 300.0
    write_tile(tmp_path / "a.tif", h[:, :6], -84.0, 36.5, res)
    other = h[:, 5:].copy()
    other[3, 0] += 7.0  # the shared column disagrees at one post
    write_tile(tmp_path / "b.tif", other, -84.0 + 5 * res, 36.5, res)
    store = TileStore(tmp_path)
    with pytest.raises(DemError, match="a.tif.*b.tif|b.tif.*a.tif"):
        store.void_fraction()
    for priority, want in (("first", h[3, 5]), ("last", h[3, 5] + 7.0)):
        s = TileStore(tmp_path, priority=priority)
        lat = s.lat_north - 3 * s.dlat
        lon = s.lon_west + 5 * s.dlon
        assert s.height(lat, lon) == pytest.approx(want)
        assert s.priority_posts == 1


def test_voids_are_nan_never_zero(tmp_path):
    res = 1 / 1200
    h = np.full((8, 8), 500.0)
    h[2:4, 2:4] = -9999.0
    write_tile(tmp_path / "v.tif", h, -84.0, 36.5, res)
    s = TileStore(tmp_path)
    assert math.isnan(s.height(s.lat_north - 2.5 * s.dlat, s.lon_west + 2.5 * s.dlon))
    assert s.height(s.lat_north - 6.5 * s.dlat, s.lon_west + 6.5 * s.dlon) == 500.0
    assert s.scan()["void_posts"] == 4


@pytest.mark.parametrize("case, needle", [
    ("empty", "no DEM tiles"),
    ("disagree", "disagree"),
    ("corrupt", "not a readable DEM"),
    ("mixed", "different post spacing"),
    ("misaligned", "not on the posts"),
    ("projected", "geographic"),
])
def test_bad_tile_directories_are_one_line_exit_2(tmp_path, navgate_run, case, needle):
    res = 1 / 1200
    d = tmp_path / case
    d.mkdir()
    h = np.full((20, 20), 400.0)
    if case == "corrupt":
        write_tile(d / "good.tif", h, -84.0, 36.5, res)
        (d / "bad.dt1").write_bytes(b"UHL1" + bytes(range(200)))
    elif case == "disagree":  # a shared column of posts with two different heights
        write_tile(d / "a.tif", h, -84.0, 36.5, res)
        write_tile(d / "b.tif", h + 1.0, -84.0 + 19 * res, 36.5, res)
    elif case == "mixed":
        write_tile(d / "a.tif", h, -84.0, 36.5, res)
        write_tile(d / "b.tif", h, -84.0 + 19 * res, 36.5, res / 3)
    elif case == "misaligned":
        write_tile(d / "a.tif", h, -84.0, 36.5, res)
        write_tile(d / "b.tif", h, -84.0 + 19.4 * res, 36.5, res)
    elif case == "projected":
        with rasterio.open(d / "p.tif", "w", driver="GTiff", width=20, height=20, count=1,
                           dtype="float32", crs="EPSG:32616",
                           transform=from_origin(700000, 4000000, 30, 30)) as dst:
            dst.write(h.astype("float32"), 1)
    for args in (["tiles", "info", d], ["fly", "--dem", d, "--duration", "5",
                                        "--out", tmp_path / "o"]):
        code, _, err = navgate_run(args)
        assert code == 2, err
        assert needle in navgate_run.one_line(err)
    with pytest.raises(DemError):
        load_terrain(d).scan()  # refused when opened, or (overlaps) on the first full pass


@pytest.mark.parametrize("args, needle", [
    (["--into", "0x2"], "between 1 and 256"),
    (["--into", "2by2"], "ROWSxCOLS"),
    (["--into", "200x200"], "cannot be cut"),
])
def test_split_refuses_impossible_grids(tmp_path, navgate_run, args, needle):
    code, _, err = navgate_run(["tiles", "split", "default", *args, "--out", tmp_path / "t"])
    assert code == 2
    assert needle in navgate_run.one_line(err)
    assert not (tmp_path / "t").exists()


def test_tile_options_need_a_tile_directory(tmp_path, navgate_run):
    code, _, err = navgate_run(["fly", "--tile-cache-mb", "1", "--duration", "5",
                                "--out", tmp_path])
    assert code == 2 and "tile directory" in navgate_run.one_line(err)


def test_a_new_split_replaces_the_directory_tiles_as_a_whole(tmp_path, navgate_run):
    out = tmp_path / "T"
    assert navgate_run(["tiles", "split", "default", "--into", "3x3", "--out", out])[0] == 0
    (out / "notes.txt").write_text("mine")  # not a tile: left alone
    code, _, err = navgate_run(["tiles", "split", "default", "--into", "2x2", "--out", out])
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == [
        "notes.txt", "tile_r0_c0.tif", "tile_r0_c1.tif", "tile_r1_c0.tif", "tile_r1_c1.tif",
        "tiles.json"]
    info = json.loads((out / "tiles.json").read_text())
    assert info["tile_count"] == 4 and info["directory"] == str(out)
    code, _, err = navgate_run(["tiles", "info", out])
    assert code == 0, err
    # a failed split leaves the directory exactly as it was
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    code, _, err = navgate_run(["tiles", "split", "default", "--into", "200x200", "--out", out])
    assert code == 2
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    # a tile of the directory that is the DEM being split is not removed
    code, _, err = navgate_run(["tiles", "split", out / "tile_r1_c1.tif", "--into", "1x1",
                                "--out", out])
    assert code == 2 and "tile_r1_c1.tif is the input" in navgate_run.one_line(err)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_disagreeing_overlaps_say_what_differs_a_void_included(tmp_path):
    res = 1 / 1200
    h = np.arange(100, dtype=float).reshape(10, 10) + 300.0
    write_tile(tmp_path / "a.tif", h[:, :6], -84.0, 36.5, res)
    other = h[:, 5:].copy()
    other[3, 0] = -9999.0  # void in b, a height in a
    write_tile(tmp_path / "b.tif", other, -84.0 + 5 * res, 36.5, res)
    with pytest.raises(DemError) as caught:
        TileStore(tmp_path).void_fraction()
    message = str(caught.value)
    assert "differ at 1 shared posts" in message and "void in one tile" in message
    assert "0 m" not in message
    other[3, 0] = h[3, 5] + 7.0
    other[4, 0] = -9999.0
    write_tile(tmp_path / "b.tif", other, -84.0 + 5 * res, 36.5, res)
    with pytest.raises(DemError, match=r"largest height difference 7 m; 1 of them void"):
        TileStore(tmp_path).void_fraction()
