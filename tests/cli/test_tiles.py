"""`navgate tiles split|info` as a user runs them: outputs, summary figures, one-line errors."""

import json
import subprocess
import sys

import numpy as np
import rasterio
from rasterio.transform import from_origin


def navgate(*args):
    return subprocess.run([sys.executable, "-m", "navgate.cli", *args], capture_output=True,
                          text=True, timeout=300)


def one_line_error(proc, needle):
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("navgate tiles"), proc.stderr
    assert needle in lines[0], lines[0]
    assert "Traceback" not in proc.stderr


def test_split_then_info(tmp_path):
    tdir, idir = tmp_path / "t", tmp_path / "i"
    proc = navgate("tiles", "split", "default", "--into", "2x3", "--out", str(tdir), "--quiet")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in tdir.glob("*.tif")) == [
        f"tile_r{a}_c{b}.tif" for a in range(2) for b in range(3)]
    proc = navgate("tiles", "info", str(tdir), "--out", str(idir))
    assert proc.returncode == 0, proc.stderr
    info = json.loads((idir / "tiles.json").read_text())
    assert info["posts"] == [344, 403] and info["gap_posts"] == 0 and info["tile_count"] == 6
    # edge posts shared: the tiles' rows and columns add up to the DEM's plus the shared ones
    assert sum(t["rows"] for t in info["tiles"][::3]) == 344 + 1
    assert sum(t["cols"] for t in info["tiles"][:3]) == 403 + 2


def test_bad_inputs_are_one_line_errors(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    one_line_error(navgate("tiles", "info", str(empty)), "no DEM tiles")
    one_line_error(navgate("tiles", "split", "default", "--into", "2by2", "--out",
                           str(tmp_path / "o")), "ROWSxCOLS")
    one_line_error(navgate("tiles", "split", "default", "--into", "300x2", "--out",
                           str(tmp_path / "o")), "between 1 and 256")
    bad = tmp_path / "bad"
    bad.mkdir()
    d = 1 / 1200
    for name, value, west in (("a.tif", 100.0, -84.0), ("b.tif", 101.0, -84.0 + 4 * d)):
        with rasterio.open(bad / name, "w", driver="GTiff", height=5, width=5, count=1,
                           dtype="float64", crs="EPSG:4326",
                           transform=from_origin(west, 36.0, d, d)) as dst:
            dst.write(np.full((5, 5), value), 1)
    one_line_error(navgate("tiles", "info", str(bad)), "disagree")
    (bad / "b.tif").write_bytes(b"not a tiff")
    one_line_error(navgate("tiles", "info", str(bad)), "b.tif")
