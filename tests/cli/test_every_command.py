"""Every command and sub-command of ``navgate`` through the same hostile-output checks
(issue 31): discovered from the click group, so that a new command cannot skip them.

For every output option of every command (``--out``, and ``fly --record``):

- ``OPT ''`` is an error: one line, exit 2;
- ``OPT INPUT`` (the output is one of the run's input files) is refused with one line, exit 2,
  and the input is unchanged; for a command that writes a directory, an input lying where one
  of its output files goes (``OUT/NAME``) is refused the same way, before the run;
- ``OPT FILE/sub`` (the output under a regular file) is one line, exit 2;
- never a traceback, never an "internal error".

Late failures (:func:`test_failed_run_leaves_previous_results`): a full disk (a ``/dev/full``
file planted in the staging, so the command's own writer meets a real ENOSPC) and a real
SIGINT in the middle of writing an output, for every command that writes: one line, exit 2 or
130, every previous output byte for byte as it was, no staging left.

Absurd numbers (:func:`test_absurd_numbers_are_one_line`): inf, nan, 1e300, 10^30 in every
numeric option discovered from the group: one line naming the option, exit 2.

A command that writes nothing is listed in :data:`NO_OUTPUTS` with the reason; a command with
no input file says so in :data:`CASES` (``inputs`` empty). The invocations are the cheapest
that reach the check (every check fails before the long part of a run).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import click
import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from navgate.cli import cli

G0 = 9.80665

#: commands (paths of names) that write no file, and why
NO_OUTPUTS = {
    ("trn-serve",): "a network/serial service: it answers requests and writes no file",
    ("cache", "info"): "reads the cache root and prints its sizes; writes no file",
    ("cache", "clear"): "deletes cache entries under the cache root only (its own refusal "
                        "of paths outside the root is tested in tests/cli/test_cache.py)",
}


def leaves(group: click.Group = cli, path: tuple = ()) -> list[tuple]:
    """Every runnable command under ``group``, as the names typed after ``navgate``."""
    ctx = click.Context(group)
    found = []
    for name in group.list_commands(ctx):
        command = group.get_command(ctx, name)
        if isinstance(command, click.Group):
            found += leaves(command, (*path, name))
        else:
            found.append((*path, name))
    return found


def command_of(path: tuple) -> click.Command:
    command = cli
    for name in path:
        command = command.get_command(click.Context(command), name)
    return command


@dataclass
class Case:
    """How to run one command cheaply: its arguments (without the output option), the output
    options it has (option -> "dir" or "file"), its input files, and for a directory output
    the name of one file it writes there."""

    args: list
    outputs: dict
    inputs: list = field(default_factory=list)
    writes: str | None = None


def _packets() -> bytes:
    """A few TinyKalman UART packets (decode refuses a capture without one)."""
    from navgate.systems.tinykalman.model import encode_packet

    return b"".join(encode_packet(k, -k) for k in range(3))


def _imu_csv(path: Path, n: int = 200, hz: float = 100.0) -> Path:
    t = np.arange(n) / hz
    cols = [t, np.zeros((n, 3)), np.tile([0.0, 0.0, -G0], (n, 1))]
    np.savetxt(path, np.column_stack(cols), delimiter=",", header="t,gx,gy,gz,ax,ay,az",
               comments="", fmt="%.10g")
    return path


def _dem(path: Path) -> Path:
    transform = from_origin(-84.3, 36.7, 1 / 1200, 1 / 1200)
    rng = np.random.default_rng(0)
    with rasterio.open(path, "w", driver="GTiff", width=400, height=400, count=1,
                       dtype="float32", crs="EPSG:4326", transform=transform) as d:
        d.write(rng.uniform(200, 600, (400, 400)).astype("float32"), 1)
    return path


def _record_log(path: Path) -> Path:
    """A short but valid record log (the format of navgate.systems.ins_trn.ps.records)."""
    from navgate.systems.ins_trn.ps.records import MAGIC

    lines = [MAGIC, 'H {"ideal": false}']
    lines += [f"I,{k / 400!r},0,0,0,0,0,-16000" for k in range(1, 9)]
    path.write_text("\n".join(lines) + "\n")
    return path


def _liberty(path: Path) -> Path:
    path.write_text("library (x) { }\n")
    return path


def make_case(path: tuple, d: Path) -> Case:
    """The cheap invocation of each command; the files are made in ``d`` by the case."""
    name = " ".join(path)
    if name == "fly":
        dem = _dem(d / "dem.tif")
        return Case(["fly", "--dem", dem, "--duration", 5, "--no-trn", "--quiet"],
                    {"--out": "dir", "--record": "file"}, [dem], "trajectory.csv")
    if name == "replay":
        log = _record_log(d / "flight.log")
        return Case(["replay", log, "--no-trn", "--quiet"], {"--out": "dir"}, [log],
                    "summary.json")
    if name == "campaign":
        dem = _dem(d / "dem.tif")
        return Case(["campaign", "--seeds", "0", "--duration", 5, "--dem", dem, "--quiet"],
                    {"--out": "dir"}, [dem], "results.csv")
    if name == "ahrs":
        log = _imu_csv(d / "imu.csv")
        return Case(["ahrs", log, "--quiet"], {"--out": "file"}, [log])
    if name == "gpsins":  # a simulation: no input file
        return Case(["gpsins", "--duration", 5, "--quiet"], {"--out": "dir"})
    if name == "kf2x2":  # a simulation: no input file
        return Case(["kf2x2", "--frames", 10], {"--out": "dir"})
    if name == "build":
        lib = _liberty(d / "cells.lib")
        return Case(["build", "fixed_mul", "--asic", "sg13g2", "--liberty", lib],
                    {"--out": "dir"}, [lib], "fixed_mul.v")
    if name == "report":
        lib = _liberty(d / "cells.lib")
        return Case(["report", "--asic", "sg13g2", "--liberty", lib], {"--out": "file"}, [lib])
    if name == "tinykalman run":
        log = _imu_csv(d / "imu.csv")
        return Case(["tinykalman", "run", log, "--quiet"], {"--out": "dir"}, [log],
                    "mpu6500_words.csv")
    if name == "tinykalman decode":
        capture = d / "uart.bin"
        capture.write_bytes(bytes(range(256)) + _packets())
        return Case(["tinykalman", "decode", capture, "--quiet"], {"--out": "dir"}, [capture],
                    "roll_pitch.csv")
    if name == "tiles split":
        dem = _dem(d / "dem.tif")
        return Case(["tiles", "split", dem, "--into", "1x2", "--quiet"], {"--out": "dir"},
                    [dem], "tiles.json")
    if name == "tiles info":
        tiles = d / "tiles"
        tiles.mkdir()
        _dem(tiles / "a.tif")
        return Case(["tiles", "info", tiles, "--quiet"], {"--out": "dir"}, [tiles / "a.tif"],
                    "tiles.json")
    raise KeyError(name)


COVERED = ["fly", "replay", "campaign", "ahrs", "gpsins", "kf2x2", "build", "report",
           "tinykalman run", "tinykalman decode", "tiles split", "tiles info"]


def test_every_command_is_covered_or_listed():
    """A new command (or sub-command) fails here until it has a case or a reason."""
    found = {" ".join(p) for p in leaves()}
    listed = set(COVERED) | {" ".join(p) for p in NO_OUTPUTS}
    assert found == listed, (sorted(found - listed), sorted(listed - found))
    assert {"fly", "replay", "tinykalman run", "tinykalman decode", "tiles split"} <= found
    for path in leaves():
        has_out = any(p.name == "out" for p in command_of(path).params)
        assert has_out == (path not in NO_OUTPUTS), path


def _snapshot(paths) -> dict:
    return {p: p.read_bytes() for p in paths}


#: the output options of each command: --out everywhere, plus fly --record
OPTIONS = {"fly": {"--out": "dir", "--record": "file"}}


def _options(name):
    return OPTIONS.get(name, {"--out": "file" if name in ("ahrs", "report") else "dir"})


def test_output_options_are_the_ones_checked():
    """Every option that names an output is in OPTIONS: a new output option fails here."""
    for name in COVERED:
        params = {p.name for p in command_of(tuple(name.split())).params}
        extra = {p for p in params if p in ("record_path",)}
        assert ("--record" in _options(name)) == bool(extra), name


@pytest.mark.parametrize("name, option", [(n, o) for n in COVERED for o in _options(n)])
def test_hostile_outputs(name, option, tmp_path, navgate_run):
    case = make_case(tuple(name.split()), tmp_path)
    assert case.outputs == _options(name)
    before = _snapshot(case.inputs)

    def refused(args, needle=""):
        code, _, err = navgate_run([*case.args, *args])
        line = navgate_run.one_line(err)
        assert code == 2, err
        assert needle in line, line
        assert _snapshot(case.inputs) == before  # no input touched
        return line

    # 1. an empty output path
    refused([option, ""], option)
    # 2. the output is one of the inputs
    for source in case.inputs:
        refused([option, source])
    if case.outputs[option] == "dir" and case.writes and case.inputs:
        # an input where one of the outputs goes: OUT/NAME
        out = case.inputs[0].parent
        target = out / case.writes
        if case.inputs[0] != target:
            case.inputs[0].rename(target)
            case.args = [target if a == case.inputs[0] else a for a in case.args]
            case.inputs[0] = target
            before = _snapshot(case.inputs)
        refused([option, out], "is the input")
    # 3. the output under a regular file
    blocker = tmp_path / "plain-file"
    blocker.write_text("x")
    refused([option, blocker / "sub"])
    assert blocker.read_text() == "x"
    # no staging left behind anywhere
    assert not [p for p in tmp_path.rglob("*navgate-tmp*")]


# ---------------------------------------------------------------------------------------------
# a full disk or a Ctrl-C late in a complete run, for every command that writes a file


@dataclass
class Run:
    """A complete, cheap run of one command: its arguments (without ``--out``), its ``--out``
    kind, the files it writes there (planted beforehand as the "previous results"), and the
    output that finds the disk full (``full``) and the one the Ctrl-C arrives at (``stop``):
    a name in the output directory, or ``"--out"`` / ``"--record"`` for an output file."""

    args: list
    kind: str
    writes: list
    full: str
    stop: str
    record: bool = False


def _short_log(d: Path) -> Path:
    """A 2 s INS-only record log written by the library (what ``fly --record`` writes)."""
    from navgate.cli import main

    log = d / "flight.log"
    try:
        main(["fly", "--duration", "2", "--no-trn", "--quiet", "--record", str(log),
              "--out", str(d / "fly-for-log")])
    except SystemExit as exit_:
        assert exit_.code == 0
    return log


def _fast_campaign(monkeypatch):
    """The campaign's LocalCluster with threads, not processes (the write is the same)."""
    import dask.distributed

    real = dask.distributed.LocalCluster
    monkeypatch.setattr(dask.distributed, "LocalCluster",
                        lambda **k: real(**{**k, "processes": False}))


def _short_gpsins(monkeypatch):
    """gpsins simulates 60 s of its (at least 250 s) flight: the writing is the same."""
    import dataclasses

    from navgate.systems.gpsins import scenario

    real = scenario.simulate
    monkeypatch.setattr(scenario, "simulate", lambda cfg, progress=None: real(
        dataclasses.replace(cfg, duration_s=60.0, outage_start_s=40.0, outage_s=10.0),
        progress))


def _canned_report(monkeypatch):
    """report's table without synthesising 48 blocks (minutes): the file write is the same."""
    from navgate.cli import build

    monkeypatch.setattr(build, "report_markdown", lambda *a, **k: "| block |\n|---|\n" * 2000)


def make_run(name: str, d: Path, monkeypatch) -> Run:
    if name == "fly":
        return Run(["fly", "--dem", _dem(d / "dem.tif"), "--duration", 2, "--no-trn",
                    "--quiet"], "dir", ["summary.json", "trajectory.csv", "trn_fixes.csv",
                                        "track.png", "errors.png"], "track.png", "--record",
                   record=True)
    if name == "replay":
        return Run(["replay", _short_log(d), "--no-trn", "--quiet"], "dir",
                   ["summary.json", "trajectory.csv", "track.png", "errors.png"],
                   "trajectory.csv", "summary.json")
    if name == "campaign":
        _fast_campaign(monkeypatch)
        return Run(["campaign", "--seeds", "0", "--duration", 2, "--dem", _dem(d / "dem.tif"),
                    "--workers", 1, "--quiet"], "dir",
                   ["results.csv", "error_cdf.png", "nees_hist.png", "summary.json"],
                   "nees_hist.png", "results.csv")
    if name == "ahrs":
        return Run(["ahrs", _imu_csv(d / "imu.csv"), "--quiet"], "file", [], "--out", "--out")
    if name == "gpsins":
        _short_gpsins(monkeypatch)
        return Run(["gpsins", "--duration", 250, "--outage-start", 200, "--filter", "seed",
                    "--rate", 20, "--quiet"], "dir",
                   ["trajectory.csv", "gps.csv", "errors.png", "summary.json"], "errors.png",
                   "summary.json")
    if name == "kf2x2":
        return Run(["kf2x2", "--frames", 200], "dir", ["summary.json", "frames.csv", "rlc.png"],
                   "rlc.png", "frames.csv")
    if name == "build":
        return Run(["build", "fixed_mul"], "dir",
                   ["fixed_mul.v", "fixed_mul.json", "fixed_mul.utilization.json"],
                   "fixed_mul.v", "fixed_mul.utilization.json")
    if name == "report":
        _canned_report(monkeypatch)
        return Run(["report"], "file", [], "--out", "--out")
    if name == "tinykalman run":
        return Run(["tinykalman", "run", _imu_csv(d / "imu.csv"), "--quiet"], "dir",
                   ["mpu6500_words.csv", "uart.bin", "roll_pitch.csv", "summary.json"],
                   "mpu6500_words.csv", "roll_pitch.csv")
    if name == "tinykalman decode":
        capture = d / "uart.bin"
        capture.write_bytes(bytes(range(256)) + _packets())
        return Run(["tinykalman", "decode", capture, "--quiet"], "dir",
                   ["roll_pitch.csv", "summary.json"], "roll_pitch.csv", "summary.json")
    if name == "tiles split":
        return Run(["tiles", "split", _dem(d / "dem.tif"), "--into", "1x2", "--quiet"], "dir",
                   ["tile_r0_c0.tif", "tile_r0_c1.tif", "tiles.json"], "tile_r0_c1.tif",
                   "tiles.json")
    if name == "tiles info":
        tiles = d / "tiles"
        tiles.mkdir()
        _dem(tiles / "a.tif")
        return Run(["tiles", "info", tiles, "--quiet"], "dir", ["tiles.json"], "tiles.json",
                   "tiles.json")
    raise KeyError(name)


def _full_disk_at(monkeypatch, target: str, final: Path):
    """The staging of ``final`` (the output directory, or one output file) has its file
    ``target`` on a full disk: a symbolic link to /dev/full, planted in the staging directory
    as it is made, so that the command's own writer (csv, numpy, matplotlib, GDAL, json)
    opens it and the kernel answers ENOSPC."""
    from navgate.cli import outputs

    real = outputs._stage_beside

    def stage(path, directory):
        staged = real(path, directory)
        if Path(path) == final:
            if directory:
                (staged / target).symlink_to("/dev/full")
            else:
                staged.unlink()
                staged.symlink_to("/dev/full")
        return staged

    monkeypatch.setattr(outputs, "_stage_beside", stage)


def _ctrl_c_at(monkeypatch, target: str | None, final: Path):
    """A real SIGINT (the command's own handler catches it) just after the command opens the
    staged ``target`` (a name in the staged output directory, or None for the staged output
    file ``final``): the run is interrupted in the middle of writing it."""
    import builtins
    import io
    import signal

    real = builtins.open

    def hit(file) -> bool:
        if not isinstance(file, (str, Path)):
            return False
        p = Path(file)
        if target is None:
            return p.name.startswith(f".{final.name}.navgate-tmp-")
        return p.name == target and p.parent.name.startswith(f".{final.name}.navgate-tmp-")

    def opened(file, *args, **kwargs):
        handle = real(file, *args, **kwargs)
        if hit(file):
            signal.raise_signal(signal.SIGINT)
        return handle

    monkeypatch.setattr(builtins, "open", opened)
    monkeypatch.setattr(io, "open", opened)


#: every command that writes a file (a new one needs a :func:`make_run`)
WRITERS = list(COVERED)


@pytest.mark.parametrize("failure", ["disk full", "ctrl-c"])
@pytest.mark.parametrize("name", WRITERS)
def test_failed_run_leaves_previous_results(name, failure, tmp_path, navgate_run,
                                            monkeypatch):
    """A full disk or a Ctrl-C late in a complete run of every command: one line, exit 2
    ("No space left on device", naming the final path, not the staging) or 130, every
    previous output byte for byte as it was (an old 13.5 MB words file was once left at 33
    bytes, a record log at 3.7 KB), nothing new in the output directory, no staging left."""
    if failure == "disk full" and not Path("/dev/full").exists():
        pytest.skip("no /dev/full (a Linux device) to stand for a full disk")
    run = make_run(name, tmp_path, monkeypatch)
    out = tmp_path / ("out" if run.kind == "dir" else "out.txt")
    planted = [out / n for n in run.writes] if run.kind == "dir" else [out]
    args = [*run.args, "--out", out]
    finals = {"--out": out}
    if run.record:
        finals["--record"] = tmp_path / "flight.log"
        planted.append(finals["--record"])
        args += ["--record", finals["--record"]]
    for p in planted:
        p.parent.mkdir(exist_ok=True)
        p.write_text(f"previous {p.name}\n")
    before = _snapshot(planted)
    target = run.full if failure == "disk full" else run.stop
    final = finals.get(target, out)
    if failure == "disk full":
        _full_disk_at(monkeypatch, None if target in finals else target, final)
    else:
        _ctrl_c_at(monkeypatch, None if target in finals else target, final)
    code, _, err = navgate_run(args)
    line = navgate_run.one_line(err)
    if failure == "disk full":
        assert code == 2 and "No space left on device" in line, line
        # named by its final path, not the staging path
        assert str(final) in line and "navgate-tmp" not in line, line
    else:
        assert code == 130 and "interrupted" in line, line
    assert _snapshot(planted) == before
    if run.kind == "dir":
        assert sorted(p.name for p in out.iterdir()) == sorted(run.writes)
    assert not [p for p in tmp_path.rglob("*navgate-tmp*")]


# ---------------------------------------------------------------------------------------------
# absurd numbers in every numeric option of every command


ABSURD = {"float": ["inf", "-inf", "nan", "1e300", "-1e300"],
          "integer": [str(10**30), str(-10**30)]}
#: options that carry numbers in text
ABSURD_TEXT = {"--seeds": ["0-1e300", f"0-{10**30}", "1e300"],
               "--ecp5-seeds": [str(2**31), str(10**30), ",".join(["1"] * 65)],
               "--nexus-seeds": [str(2**31), str(10**30)],
               "--into": [f"{10**30}x1", "infxinf", "1e300x2"]}

#: (command, option, value) that are accepted, with the reason (they are not run here)
ACCEPTED = {
    **{(c, "--seed", str(10**30)): "any non-negative integer seeds NumPy's generator"
       for c in ("fly", "gpsins", "kf2x2")},
    ("tinykalman run", "--limit", str(10**30)): "a limit beyond the log reads all of it",
    ("trn-serve", "--cache-mb", "1e300"): "a cache larger than the tiles holds them all",
    ("trn-serve", "--max-requests", str(10**30)): "a service answers until it is stopped",
}


def _absurd_bases(d: Path) -> dict:
    """Runs that would succeed, so that the value under test is what a refusal is about."""
    dem = _dem(d / "dem.tif")
    tiles = d / "tiles"
    tiles.mkdir()
    _dem(tiles / "a.tif")
    return {
        "fly": ["fly", "--dem", dem, "--duration", 2, "--no-trn", "--quiet"],
        "replay": ["replay", _record_log(d / "flight.log"), "--no-trn", "--quiet"],
        "campaign": ["campaign", "--seeds", "0", "--duration", 2, "--dem", dem, "--quiet",
                     "--workers", 1],
        "ahrs": ["ahrs", _imu_csv(d / "imu.csv"), "--quiet"],
        "gpsins": ["gpsins", "--duration", 250, "--outage-start", 200, "--rate", 20,
                   "--filter", "seed", "--quiet"],
        "kf2x2": ["kf2x2", "--frames", 10],
        "build": ["build", "fixed_mul", "--timing"],
        "report": ["report", "--asic", "sg13g2", "--liberty", _liberty(d / "cells.lib")],
        "tinykalman run": ["tinykalman", "run", _imu_csv(d / "imu.csv"), "--quiet"],
        "tinykalman decode": ["tinykalman", "decode", "--serial", "loop://", "--seconds", 1,
                              "--quiet"],
        "tiles split": ["tiles", "split", dem, "--into", "1x2", "--quiet"],
        "tiles info": ["tiles", "info", tiles, "--quiet"],
        "trn-serve": ["trn-serve", "--tiles", tiles, "--listen", "tcp://127.0.0.1:0"],
        "cache info": ["cache", "info"],
        "cache clear": ["cache", "clear"],
    }


def _numeric_options(path: tuple) -> list[tuple[str, str]]:
    found = []
    for p in command_of(path).params:
        if not isinstance(p, click.Option):
            continue
        opt = max(p.opts, key=len)
        kind = p.type.name.split()[0]
        for value in ABSURD_TEXT.get(opt, ABSURD.get(kind, [])):
            found.append((opt, value))
    return found


@pytest.mark.parametrize("path", leaves(), ids=" ".join)
def test_absurd_numbers_are_one_line(path, tmp_path, navgate_run):
    """inf, nan, 1e300, 10^30 in every numeric option of every command (discovered from
    the click group): one line naming the option (or the value), exit 2, before the long
    run; never an internal error (--trn-timeout 1e10 and trn-serve --fd 10^30 overflowed
    C types; --ecp5-seeds 10^30 reached nextpnr)."""
    import signal

    name = " ".join(path)
    base = [str(a) for a in _absurd_bases(tmp_path)[name]]
    cases = [(o, v) for o, v in _numeric_options(path) if (name, o, v) not in ACCEPTED]
    if name == "trn-serve":  # --fd and --serial are other ways to serve than --listen
        cases = [(o, v) for o, v in cases if o != "--fd"] + [("--fd", str(10**30))]

    def hang(*_):
        raise TimeoutError("no answer within 60 s")

    previous = signal.signal(signal.SIGALRM, hang)
    try:
        for opt, value in cases:
            args = list(base)
            if opt in args:  # replace the base's value
                i = args.index(opt)
                del args[i:i + 2]
            if name == "trn-serve" and opt == "--fd":
                args = args[:args.index("--listen")]
            signal.alarm(60)
            code, _, err = navgate_run([*args, f"{opt}={value}"])
            signal.alarm(0)
            line = navgate_run.one_line(err)
            assert code == 2, (opt, value, line)
            try:
                shown = f"{float(value):g}"
            except ValueError:
                shown = value
            # (an option whose value is optional, fly --realtime [SPEED], takes "-inf" for
            # another option: click's own one-line refusal)
            optional = value.startswith("-") and "No such option" in line
            assert opt in line or shown in line or value in line or optional, (opt, value,
                                                                               line)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def test_inputs_that_are_not_regular_files_are_named(tmp_path, navgate_run):
    """A Liberty file or a tile directory that is a device or a FIFO: "not a regular
    file" / "not a tile directory", not "not found" (it exists)."""
    import os

    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for bad in ("/dev/zero", fifo, tmp_path):
        code, _, err = navgate_run(["build", "fixed_mul", "--asic", "sg13g2", "--liberty", bad])
        assert code == 2 and "not a regular file" in navgate_run.one_line(err), err
        code, _, err = navgate_run(["report", "--asic", "sg13g2", "--liberty", bad])
        assert code == 2 and "not a regular file" in navgate_run.one_line(err), err
    for bad in ("/dev/zero", fifo):
        code, _, err = navgate_run(["tiles", "info", bad])
        assert code == 2 and "not a tile directory" in navgate_run.one_line(err), err


def test_no_output_inside_an_input_directory(tmp_path, navgate_run):
    """README: no output may be "a file inside an input directory" (a tile directory that a
    later run reads); tiles info --out TILES/sub and fly --record TILES/f.log wrote there."""
    tiles = tmp_path / "tiles"
    tiles.mkdir()
    _dem(tiles / "a.tif")
    for args in (["tiles", "info", tiles, "--out", tiles / "sub"],
                 ["fly", "--dem", tiles, "--duration", 2, "--no-trn", "--out", tiles / "x"],
                 ["fly", "--dem", tiles, "--duration", 2, "--no-trn", "--out", tmp_path / "o",
                  "--record", tiles / "f.log"]):
        code, _, err = navgate_run(args)
        assert code == 2 and "inside the input directory" in navgate_run.one_line(err), err
    assert sorted(p.name for p in tiles.iterdir()) == ["a.tif"]


@pytest.mark.parametrize("name", WRITERS)
def test_results_on_stdout_notes_on_stderr(name, tmp_path, navgate_run, monkeypatch):
    """README: results (tables) go to stdout; progress, notes and "wrote ..." lines to stderr
    (`navgate CMD > run.log` captures the results). A complete run of every command that
    writes, which also writes every file it declares (tinykalman printed its table on
    stderr)."""
    run = make_run(name, tmp_path, monkeypatch)
    out = tmp_path / ("out" if run.kind == "dir" else "out.txt")
    args = [*(a for a in run.args if a != "--quiet"), "--out", out]
    if run.record:
        args += ["--record", tmp_path / "flight.log"]
    code, stdout, stderr = navgate_run(args)
    assert code == 0, stderr
    assert stdout.strip(), "no result on stdout"
    assert "wrote" in stderr and "wrote" not in stdout, (stdout, stderr)
    assert "┏" not in stderr and "Traceback" not in stderr
    if run.kind == "dir":
        assert set(run.writes) <= {p.name for p in out.iterdir()}
    else:
        assert out.stat().st_size > 0


def test_python_dash_m_navgate_is_the_command():
    """``python -m navgate`` runs the ``navgate`` command (as ``python -m navgate.cli``)."""
    import subprocess
    import sys

    from navgate import __version__

    got = subprocess.run([sys.executable, "-m", "navgate", "--version"], capture_output=True,
                         text=True, timeout=120)
    assert got.returncode == 0, got.stderr
    assert __version__ in got.stdout
