"""``navgate build --asic sg13g2``: IHP SG13G2 pre-layout area, flip-flops and tile fit."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from navgate.hw.asic import (
    LIBERTY_NAME,
    TILES,
    liberty_cells,
    smallest_tile,
    synthesize_asic,
)

# the Liberty file in ../shared/asic beside the checkout
LIBERTY = Path(__file__).resolve().parents[3] / "shared" / "asic" / LIBERTY_NAME
needs_liberty = pytest.mark.skipif(not LIBERTY.is_file(), reason=f"{LIBERTY} absent")

# a 4-bit counter with a synchronous reset: four flip-flops and their increment logic
COUNTER = """
module counter4(input clk, input rst, output reg [3:0] q);
  always @(posedge clk) if (rst) q <= 4'd0; else q <= q + 4'd1;
endmodule
"""
# its SG13G2 area: 4 sg13g2_dfrbpq_1 (48.9888 each) and 9 gates, Yosys 0.70
COUNTER_AREA = 279.4176


def navgate(*args: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "navgate.cli", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=300)


def test_smallest_tile_at_65_percent():
    one = 202.08 * 154.98
    two = 202.08 * 313.74
    assert TILES["1x1"] == (202.08, 154.98)
    assert smallest_tile(0.65 * one - 0.01) == "1x1"
    assert smallest_tile(0.65 * one + 0.01) == "1x2"
    assert smallest_tile(0.65 * two - 0.01) == "1x2"
    assert smallest_tile(0.65 * two + 0.01) is None


@needs_liberty
def test_liberty_scan_finds_areas_and_flip_flops():
    cells = liberty_cells(LIBERTY)
    # from the library text: the reset flip-flop and the 1x inverter
    assert cells["sg13g2_dfrbpq_1"] == {"area": 48.9888, "ff": True, "latch": False}
    assert cells["sg13g2_inv_1"]["area"] == 5.4432 and not cells["sg13g2_inv_1"]["ff"]
    assert cells["sg13g2_dlhq_1"]["latch"] and not cells["sg13g2_dlhq_1"]["ff"]
    assert all(cell["area"] is not None for cell in cells.values())


@needs_liberty
def test_counter_area_exact(tmp_path):
    """A 4-bit counter maps to four reset flip-flops and a handful of gates; the area is the
    sum of their Liberty areas, and Yosys's own ``stat -liberty`` total agrees."""
    got = synthesize_asic(COUNTER, "counter4", tmp_path, LIBERTY)
    assert got["flip_flops"] == 4 and got["latches"] == 0
    assert got["cells_by_type"]["sg13g2_dfrbpq_1"] == 4
    cells = liberty_cells(LIBERTY)
    assert got["area_um2"] == pytest.approx(
        sum(n * cells[c]["area"] for c, n in got["cells_by_type"].items()), abs=1e-4)
    yosys_area = json.loads((tmp_path / "stat_asic.json").read_text())["design"]["area"]
    assert got["area_um2"] == pytest.approx(yosys_area, abs=1e-4)
    # Yosys 0.70's mapping of this counter (pinned: a change of flow shows here)
    assert got["area_um2"] == pytest.approx(COUNTER_AREA, abs=1e-4)
    assert got["tile"] == "1x1"


def test_absent_liberty_is_one_line_exit_2(tmp_path):
    proc = navgate("build", "kalman_steady", "--asic", "sg13g2", "--liberty",
                   str(tmp_path / "missing.lib"), "--out", str(tmp_path / "out"))
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Liberty file not found" in lines[0]
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "out").exists()


def test_unknown_asic_tech_and_stray_liberty(tmp_path):
    for args, fragment in ((("--asic", "tsmc"), "unknown ASIC technology 'tsmc'"),
                           (("--liberty", str(tmp_path / "x.lib")), "--liberty needs --asic")):
        proc = navgate("build", "kalman_steady", *args, "--out", str(tmp_path / "out"))
        assert proc.returncode == 2, proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1 and fragment in proc.stderr


@needs_liberty
def test_build_writes_asic_json(tmp_path):
    proc = navgate("build", "kalman_steady", "--asic", "sg13g2", "--liberty", str(LIBERTY),
                   "--out", str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    asic = json.loads((tmp_path / "kalman_steady.asic.json").read_text())
    assert {"cells", "flip_flops", "area_um2", "tile"} <= set(asic)
    # the xc7 flow counts 33 flip-flops for this block; the standard cells hold the same state
    use = json.loads((tmp_path / "kalman_steady.utilization.json").read_text())
    assert asic["flip_flops"] == use["ff"] == 33
    assert asic["tile"] == "1x1"
    assert f"{asic['flip_flops']} flip-flops; fits 1x1" in proc.stdout
    assert asic["timing"]["longest_path_ns"] < 100.0 and "longest path" in proc.stdout


@needs_liberty
def test_nldm_lookup_hits_the_table():
    """The interpolation returns the library's own numbers on its grid and the mean of four
    neighbours at a cell's centre (sg13g2_nand2_1, Y from A, cell_rise)."""
    from navgate.hw.asic import _lookup, liberty_timing

    nand = liberty_timing(LIBERTY, {"sg13g2_nand2_1"})["sg13g2_nand2_1"]
    arc = next(a for a in nand["pins"]["Y"]["arcs"] if a["related"] == "A")
    rise = arc["tables"]["cell_rise"]
    assert _lookup(rise, 0.0186, 0.001) == pytest.approx(0.022718, abs=1e-9)
    assert _lookup(rise, 2.5074, 0.3) == pytest.approx(2.05647, abs=1e-9)
    centre = _lookup(rise, (0.0186 + 0.0966) / 2, (0.001 + 0.0234) / 2)
    assert centre == pytest.approx((0.022718 + 0.0868603 + 0.0437056 + 0.129513) / 4, abs=1e-9)
    assert nand["pins"]["A"]["direction"] == "input" and nand["pins"]["A"]["capacitance"] > 0


@needs_liberty
def test_counter_longest_path(tmp_path):
    """The counter's longest path starts at a flip-flop's clock-to-Q and ends at a D input;
    it is longer than the bare clock-to-Q at the smallest load and grows with the counter."""
    from navgate.hw.asic import _lookup, liberty_timing

    small = synthesize_asic(COUNTER, "counter4", tmp_path / "4", LIBERTY)["timing"]
    wide = synthesize_asic(COUNTER.replace("counter4", "counter16").replace("[3:0]", "[15:0]")
                           .replace("4'd", "16'd"), "counter16", tmp_path / "16",
                           LIBERTY)["timing"]
    flop = liberty_timing(LIBERTY, {"sg13g2_dfrbpq_1"})["sg13g2_dfrbpq_1"]
    clk_q = next(a for a in flop["pins"]["Q"]["arcs"] if a["type"] == "rising_edge")
    bare = max(_lookup(clk_q["tables"][k], 0.0186, 0.001) for k in ("cell_rise", "cell_fall"))
    assert "clock-to-Q" in small["path_start"] and "(D, setup)" in small["path_end"]
    assert bare < small["longest_path_ns"] < wide["longest_path_ns"] < 100.0
    assert small["longest_path_ns"] == pytest.approx(0.5881, abs=1e-4)  # Yosys 0.70 mapping
    assert small["slack_ns"] == pytest.approx(100.0 - small["longest_path_ns"], abs=1e-4)


def test_report_asic_columns():
    """The report's SG13G2 columns come from ``BLOCK.asic.json`` (the table code only)."""
    from navgate.hw.flow import ASIC_COLUMNS, COLUMNS, asic_cells, report_table

    asic = {"area_um2": 45441.4236, "flip_flops": 420, "tile": None,
            "timing": {"longest_path_ns": 4.69594}}
    cells = asic_cells(asic)
    assert cells == ["45441.4", "420", "none", "4.696"]
    table = report_table([["b"] + ["1"] * (len(COLUMNS) - 1) + cells])
    assert table.splitlines()[0].count("|") == len(COLUMNS) + len(ASIC_COLUMNS) + 1
    assert "SG13G2 area (um2)" in table and "| 45441.4 | 420 | none | 4.696 |" in table


def test_report_absent_liberty_is_one_line(tmp_path):
    proc = navgate("report", "--asic", "sg13g2", "--liberty", str(tmp_path / "missing.lib"))
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1
    assert "Liberty file not found" in proc.stderr


@needs_liberty
def test_flip_flops_by_register(tmp_path):
    """Two registers of known widths: every flip-flop is counted under its register."""
    text = """
module two(input clk, input [2:0] d, output reg [2:0] a, output reg [4:0] b);
  always @(posedge clk) begin a <= d; b <= {b[3:0], d[1] ^ d[2]}; end
endmodule
"""
    got = synthesize_asic(text, "two", tmp_path, LIBERTY)
    assert got["flip_flops_by_register"] == {"b": 5, "a": 3}
    assert sum(got["flip_flops_by_register"].values()) == got["flip_flops"]
