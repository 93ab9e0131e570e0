"""The bad-input suite of issue 17: every class of hostile input, for every command.

Classes (one section each): output safety (failed / interrupted / disk-full runs leave the
previous results untouched, never an input overwritten, per-command default output,
``--out ''``, OSError on output as one line); console (tables on stdout, progress on stderr,
``--quiet``); tracebacks and hangs (too-short flights, binary input, unexpected exceptions,
library warnings); plausibility (impossible readings, time gaps and units, magnetometer rate,
word-length overflow, DEM units); non-finite summaries. Generic checks run over
``navgate.cli.COMMANDS`` so that a new command is covered as soon as it is registered.

Runs are in-process (``navgate.cli.main``) and short (``fly --duration 20``, ``gpsins
--duration 250``, ``kf2x2 --frames 200``) to keep CPU low; failures are injected by
monkeypatching a writer to raise ``OSError(ENOSPC)`` or ``KeyboardInterrupt`` half way.
"""

from __future__ import annotations

import errno
import importlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import click
import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from navgate.cli import COMMANDS, main

G0 = 9.80665


@pytest.fixture(autouse=True)
def own_build_cache(tmp_path_factory, monkeypatch):
    """Each test has its own build cache root (navgate.cache): a stubbed synthesis must
    neither be stored in the user's cache nor be skipped because the user's cache holds the
    block; the Verilator models stay in the user's cache."""
    from navgate.gateware.verify import verilator_cache_dir

    monkeypatch.setenv("NAVGATE_VERILATOR_CACHE", str(verilator_cache_dir()))
    monkeypatch.setenv("NAVGATE_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))


def run(args, capsys):
    """(exit code, stdout, stderr) of ``navgate ARGS`` run in-process."""
    code = 0
    try:
        main([str(a) for a in args])
    except SystemExit as exit_:
        code = exit_.code
    out = capsys.readouterr()
    return code, out.out, out.err


def assert_one_line(err, code, expected_code=2, needle=""):
    # the one-off notice of a cold Numba cache is not part of the error report
    lines = [ln for ln in err.splitlines()
             if ln.strip() and "compiling Numba kernels" not in ln]
    assert code == expected_code, err
    assert len(lines) == 1, err
    assert "Traceback" not in err and "internal error" not in err, err
    assert needle in lines[0], lines[0]
    return lines[0]


def command(name):
    module, attr = COMMANDS[name].split(":")
    return getattr(importlib.import_module(module), attr)


def out_param(name):
    return next((p for p in command(name).params if p.name == "out"), None)


def plant_previous(out: Path, names) -> dict:
    """Fake previous results: returns name -> bytes to compare after a failed run."""
    out.mkdir(parents=True, exist_ok=True)
    old = {}
    for name in names:
        (out / name).write_bytes(f"previous {name}\n".encode())
        old[name] = (out / name).read_bytes()
    return old


def assert_untouched(out: Path, old: dict):
    assert sorted(p.name for p in out.iterdir()) == sorted(old), list(out.iterdir())
    for name, content in old.items():
        assert (out / name).read_bytes() == content, name
    leftovers = [p for p in out.parent.iterdir() if ".navgate-tmp-" in p.name]
    assert not leftovers, leftovers


def imu_csv(path: Path, n=600, hz=100.0, *, mag=True, t_scale=1.0, gyro=None, t=None):
    """A stationary, level FRD log (plain header, SI units)."""
    tt = np.arange(n) / hz if t is None else t
    g = np.zeros((n, 3)) if gyro is None else gyro
    a = np.tile([0.0, 0.0, -G0], (n, 1))
    cols = [tt * t_scale, g, a]
    header = "t,gx,gy,gz,ax,ay,az"
    if mag:
        cols.append(np.tile([20.0, 0.0, 40.0], (n, 1)))
        header += ",mx,my,mz"
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=header, comments="",
               fmt="%.10g")
    return path


def enospc_after_partial():
    """A writer that leaves a truncated file and then finds the disk full."""

    def writer(*args, **kwargs):
        target = next(a for a in args if isinstance(a, (str, Path)) or hasattr(a, "write"))
        if hasattr(target, "write"):  # an open file
            target.write("truncated,")
            target = target.name
        else:
            Path(target).write_text("truncated,")
        raise OSError(errno.ENOSPC, "No space left on device", str(target))

    return writer


def interrupt(*args, **kwargs):
    raise KeyboardInterrupt


# ---------------------------------------------------------------------------------------------
# 1. output safety

# command -> (arguments of a short run, output names, "module:function" written late in it)
RUNS = {
    "fly": (["fly", "--duration", 20, "--no-trn"],
            ["summary.json", "trajectory.csv", "trn_fixes.csv", "track.png", "errors.png"],
            "navgate.systems.ins_trn.ps.report:plot_errors"),
    "gpsins": (["gpsins", "--duration", 250, "--outage-start", 200],
               ["summary.json", "trajectory.csv", "gps.csv", "errors.png"],
               "navgate.cli.gpsins:plot_errors"),
    "kf2x2": (["kf2x2", "--frames", 200], ["summary.json", "frames.csv", "rlc.png"],
              "navgate.cli.kf2x2:_plot"),
}


def patch(monkeypatch, target, replacement):
    module, attr = target.split(":")
    monkeypatch.setattr(importlib.import_module(module), attr, replacement)


@pytest.mark.parametrize("name", sorted(RUNS))
@pytest.mark.parametrize("failure", ["disk full", "interrupt"])
def test_failed_run_leaves_previous_results(name, failure, tmp_path, capsys, monkeypatch):
    args, outputs, target = RUNS[name]
    out = tmp_path / "out"
    old = plant_previous(out, outputs)
    if failure == "disk full":
        patch(monkeypatch, target, enospc_after_partial())
        code, _, err = run([*args, "--out", out, "--quiet"], capsys)
        line = assert_one_line(err, code, 2, "No space left on device")
        assert str(out) in line  # named by its final path, not the staging directory
    else:
        patch(monkeypatch, target, interrupt)
        code, _, err = run([*args, "--out", out, "--quiet"], capsys)
        assert_one_line(err, code, 130, "interrupted")
    assert_untouched(out, old)


def test_build_failed_or_interrupted_keeps_previous(tmp_path, capsys, monkeypatch):
    out = tmp_path / "hw"
    names = ["fixed_mul.v", "fixed_mul.json", "fixed_mul.utilization.json"]
    old = plant_previous(out, names)
    import navgate.hw.flow as flow

    def full(text, name, target, work):
        raise OSError(errno.ENOSPC, "No space left on device", str(work / "x.log"))

    monkeypatch.setattr(flow, "synthesize", full)
    code, _, err = run(["build", "fixed_mul", "--out", out], capsys)
    assert code == 2 and "No space left" in err and "Traceback" not in err
    assert_untouched(out, old)
    monkeypatch.setattr(flow, "synthesize", interrupt)
    code, _, err = run(["build", "fixed_mul", "--out", out], capsys)
    assert code == 130 and "Traceback" not in err
    assert_untouched(out, old)


def test_ahrs_failed_run_keeps_previous_output(tmp_path, capsys, monkeypatch):
    """A log whose time runs backwards in its third block: the error comes after two blocks
    were already filtered and written (to the staging file), the old output stays."""
    import navgate.sim.imu_log as imu_log

    monkeypatch.setattr(imu_log, "CHUNK_ROWS", 200)
    t = np.arange(600) / 100.0
    t[450] = t[449]
    src = imu_csv(tmp_path / "log.csv", t=t)
    out = tmp_path / "res"
    old = plant_previous(out, ["att.csv"])
    code, _, err = run(["ahrs", src, "--out", out / "att.csv"], capsys)
    assert_one_line(err, code, 2, "time does not increase at line 452")
    assert_untouched(out, old)
    ok = imu_csv(tmp_path / "ok.csv")
    monkeypatch.setattr(np, "savetxt", enospc_after_partial())
    code, _, err = run(["ahrs", ok, "--out", out / "att.csv"], capsys)
    assert code == 2 and "Traceback" not in err
    assert_untouched(out, old)
    monkeypatch.setattr(np, "savetxt", interrupt)
    code, _, err = run(["ahrs", ok, "--out", out / "att.csv"], capsys)
    assert_one_line(err, code, 130, "interrupted")
    assert_untouched(out, old)


def test_real_sigint_during_a_flight(tmp_path):
    """A real SIGINT to a running ``navgate fly``: exit 130, one line, old results intact,
    whenever the signal lands during the run."""
    out = tmp_path / "out"
    old = plant_previous(out, RUNS["fly"][1])
    env = dict(os.environ)
    proc = subprocess.Popen([sys.executable, "-m", "navgate.cli", "fly", "--duration", "3000",
                             "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    # the banner line comes when the flight starts (after the imports and the DEM); the 3000 s
    # flight then computes for several seconds (about 8 s on an idle core), so the signal lands
    # inside it however fast or loaded the machine is
    banner = proc.stderr.readline()
    assert banner.startswith("navgate fly: 3000 s"), banner
    time.sleep(2)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    # after the progress lines, one line says it was interrupted; no traceback
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert "Traceback" not in stderr and lines[-1].startswith("navgate fly: interrupted"), stderr
    assert sum(ln.startswith("navgate fly:") for ln in lines) == 1, stderr
    assert_untouched(out, old)


def test_interrupt_wrapped_or_swallowed_is_still_an_interrupt(tmp_path, capsys, monkeypatch):
    """A KeyboardInterrupt raised inside a numba function surfaces as ``SystemError: ...
    returned a result with an exception set`` (seen with a real SIGINT during ``fly``), and a
    library may swallow one: both still end as an interrupt (exit 130, one line) and nothing
    is committed."""
    out = tmp_path / "hw"
    names = ["fixed_mul.v", "fixed_mul.json", "fixed_mul.utilization.json"]
    old = plant_previous(out, names)
    import navgate.hw.flow as flow

    def wrapped(*a):
        try:
            os.kill(os.getpid(), signal.SIGINT)  # the CLI's handler raises KeyboardInterrupt
            time.sleep(1)
        except KeyboardInterrupt as exc:
            raise SystemError("CPUDispatcher returned a result with an exception set") from exc
        raise AssertionError("no interrupt delivered")

    monkeypatch.setattr(flow, "synthesize", wrapped)
    code, _, err = run(["build", "fixed_mul", "--out", out], capsys)
    assert_one_line(err, code, 130, "interrupted")
    assert_untouched(out, old)

    def swallowed(*a):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1)
        except KeyboardInterrupt:
            pass  # lost: the run goes on as if nothing happened
        return {"lut": 1, "ff": 1, "dsp": 0, "carry4": 0, "bram36": 0}

    monkeypatch.setattr(flow, "synthesize", swallowed)
    code, _, err = run(["build", "fixed_mul", "--out", out], capsys)
    assert_one_line(err, code, 130, "interrupted")
    assert_untouched(out, old)
    # the next command is not affected
    monkeypatch.setattr(flow, "synthesize", lambda *a: {"lut": 1, "ff": 1, "dsp": 0,
                                                        "carry4": 0, "bram36": 0})
    code, _, err = run(["build", "fixed_mul", "--out", out], capsys)
    assert code == 0, err


def test_never_overwrites_an_input(tmp_path, capsys):
    src = imu_csv(tmp_path / "gap.csv")
    before = src.read_bytes()
    code, _, err = run(["ahrs", src, "--out", src], capsys)
    assert_one_line(err, code, 2, "is the input")
    code, _, err = run(["ahrs", src, "--out", tmp_path / "." / "gap.csv"], capsys)
    assert_one_line(err, code, 2, "is the input")
    assert src.read_bytes() == before
    # a DEM that sits where fly would write one of its outputs
    out = tmp_path / "run"
    out.mkdir()
    dem = out / "trajectory.csv"
    transform = from_origin(-84.3, 36.7, 1 / 1200, 1 / 1200)
    rng = np.random.default_rng(0)
    with rasterio.open(dem, "w", driver="GTiff", width=400, height=400, count=1,
                       dtype="float32", crs="EPSG:4326", transform=transform) as d:
        d.write(rng.uniform(200, 600, (400, 400)).astype("float32"), 1)
    before = dem.read_bytes()
    code, _, err = run(["fly", "--dem", dem, "--duration", 20, "--no-trn", "--out", out,
                        "--quiet"], capsys)
    assert_one_line(err, code, 2, "is the input")
    assert dem.read_bytes() == before


def test_every_command_has_its_own_default_output():
    defaults = {}
    for name in COMMANDS:
        p = out_param(name)
        if p is not None and p.default is not None:
            defaults[name] = str(p.default)
    assert {"fly", "gpsins", "kf2x2", "build"} <= set(defaults)
    assert len(set(defaults.values())) == len(defaults), defaults
    for a in defaults.values():  # no default inside another command's default
        assert not any(b != a and Path(a).is_relative_to(b) for b in defaults.values())


@pytest.mark.parametrize("name", sorted(n for n in COMMANDS if out_param(n) is not None))
def test_empty_out_is_an_error(name, tmp_path, capsys):
    args = [name, "--out", ""]
    if name == "ahrs":
        args.insert(1, imu_csv(tmp_path / "log.csv"))
    if name == "build":
        args.insert(1, "fixed_mul")
    code, _, err = run(args, capsys)
    assert_one_line(err, code, 2, "--out")


@pytest.mark.parametrize("name", ["fly", "gpsins", "kf2x2", "build"])
def test_output_directory_errors_are_one_line(name, tmp_path, capsys, monkeypatch):
    """A file where the output directory goes, and a directory where an output file goes;
    both are found before the long run starts or before anything is moved."""
    blocker = tmp_path / "file"
    blocker.write_text("x")
    args = {"fly": ["fly", "--duration", 20, "--no-trn", "--quiet"],
            "gpsins": RUNS["gpsins"][0] + ["--quiet"], "kf2x2": RUNS["kf2x2"][0] + ["--quiet"],
            "build": ["build", "fixed_mul"]}[name]
    loud = [a for a in args if a != "--quiet"]  # nothing printed before the error either
    code, _, err = run([*loud, "--out", blocker / "sub"], capsys)
    assert_one_line(err, code, 2, "not a directory")
    if name == "build":
        import navgate.hw.flow as flow

        monkeypatch.setattr(flow, "synthesize", lambda *a: {"lut": 1, "ff": 1, "dsp": 0,
                                                            "carry4": 0, "bram36": 0})
        first = "fixed_mul.v"
    else:
        first = "summary.json"
    (tmp_path / "o" / first).mkdir(parents=True)
    code, _, err = run([*args, "--out", tmp_path / "o"], capsys)
    assert_one_line(err, code, 2, "directory is in the way")
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == [first]


def test_ahrs_output_file_errors(tmp_path, capsys):
    src = imu_csv(tmp_path / "log.csv")
    code, _, err = run(["ahrs", src, "--out", tmp_path / "ok.csv", "--quiet"], capsys)
    assert code == 0, err
    umask = os.umask(0)
    os.umask(umask)
    assert (tmp_path / "ok.csv").stat().st_mode & 0o777 == 0o666 & ~umask  # not mkstemp's 0600
    for bad, needle in ((tmp_path, "directory"), (Path("/dev/full"), "not a regular file"),
                        (tmp_path / "file" / "x.csv", "not a directory")):
        if bad.name == "x.csv":
            (tmp_path / "file").write_text("x")
        code, _, err = run(["ahrs", src, "--out", bad], capsys)
        assert_one_line(err, code, 2, needle)


def test_fly_record_under_a_file_says_it_is_not_a_directory(tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    code, _, err = run(["fly", "--duration", 2, "--no-trn", "--record",
                        tmp_path / "afile" / "x.log", "--out", tmp_path / "o"], capsys)
    assert_one_line(err, code, 2, f"{tmp_path / 'afile'} is not a directory")


def test_report_out_is_checked_before_synthesis(tmp_path, capsys):
    start = time.perf_counter()
    for bad, needle in (("/proc/x.md", "cannot write"),
                        (tmp_path / "missing" / "r.md", "does not exist"),
                        (tmp_path, "is a directory"),
                        (tmp_path / "afile" / "r.md", "afile is not a directory")):
        (tmp_path / "afile").write_text("x")
        code, _, err = run(["report", "--out", bad], capsys)
        assert_one_line(err, code, 2, needle)
    assert time.perf_counter() - start < 10  # no synthesis started (one block takes ~30 s)


# ---------------------------------------------------------------------------------------------
# 2. console: tables on stdout, progress on stderr, --quiet hides the table

TABLE_RUNS = {
    "fly": (["fly", "--duration", 20, "--ranger", "tf-luna"], "GPS-denied flight"),
    "gpsins": (RUNS["gpsins"][0], "seed 002 GPS/INS"),
    "kf2x2": (RUNS["kf2x2"][0], "kf2x2 Q(20, 10)"),
    "ahrs": (["ahrs"], "navgate ahrs: mahony"),
}


@pytest.mark.parametrize("name", sorted(TABLE_RUNS))
def test_tables_on_stdout_quiet_hides_them(name, tmp_path, capsys):
    args, title = TABLE_RUNS[name]
    if name == "ahrs":
        args = [*args, imu_csv(tmp_path / "log.csv")]
    code, out, err = run([*args, "--out", tmp_path / "a" / "o.csv" if name == "ahrs"
                          else tmp_path / "a"], capsys)
    assert code == 0, err
    assert title in out and title not in err
    assert "┏" in out and "┏" not in err  # the table's frame only on stdout
    assert "Traceback" not in err
    if name == "fly":  # a ranger that never returns says so in the table's output
        assert "0 (no fix" in out and "tf-luna" in out
    code, out, err = run([*args, "--out", tmp_path / "b" / "o.csv" if name == "ahrs"
                          else tmp_path / "b", "--quiet"], capsys)
    assert code == 0, err
    assert out == ""
    assert "┏" not in err


def test_build_result_on_stdout_files_on_stderr(tmp_path, capsys, monkeypatch):
    import navgate.hw.flow as flow

    monkeypatch.setattr(flow, "synthesize", lambda *a: {"lut": 1, "ff": 2, "dsp": 0,
                                                        "carry4": 0, "bram36": 0})
    code, out, err = run(["build", "fixed_mul", "--out", tmp_path], capsys)
    assert code == 0, err
    assert out.startswith("fixed_mul: LUT 1, FF 2") and "wrote" not in out
    assert "wrote" in err
    assert (tmp_path / "fixed_mul.v").exists()
    assert not [p for p in tmp_path.parent.iterdir() if ".navgate-tmp-" in p.name]


def test_build_list_is_plain_and_target_choices_in_help(capsys):
    code, out, _ = run(["build", "--list"], capsys)
    assert code == 0 and "``" not in out and ":class:" not in out and ":func:" not in out
    for name in ("build", "report"):
        code, out, _ = run([name, "--help"], capsys)
        assert code == 0 and "xc7z020" in out and "choices" in out
    code, out, _ = run(["report", "--help"], capsys)
    assert "--jobs" in out


# ---------------------------------------------------------------------------------------------
# 3. tracebacks and hangs


@pytest.mark.parametrize("duration", ["0.01", "0.1"])
def test_fly_too_short_is_one_line(duration, capsys, tmp_path):
    code, _, err = run(["fly", "--duration", duration, "--out", tmp_path], capsys)
    assert_one_line(err, code, 2, "--duration")


def test_ahrs_dev_zero_and_binary_do_not_hang(tmp_path):
    binary = tmp_path / "bin.csv"
    binary.write_bytes(b"t,gx,gy,gz,ax,ay,az\n" + bytes(range(256)) * 100)
    long_line = tmp_path / "long.csv"
    long_line.write_text("t,gx,gy,gz,ax,ay,az\n" + "1" * 200_000 + "\n")
    for path, needle in (("/dev/zero", "binary"), (binary, "binary"), (long_line, "longer")):
        proc = subprocess.run([sys.executable, "-m", "navgate.cli", "ahrs", str(path)],
                              capture_output=True, text=True, timeout=60)
        assert_one_line(proc.stderr, proc.returncode, 2, needle)


def test_unexpected_exception_is_one_line(monkeypatch, capsys, tmp_path):
    import navgate.cli.kf2x2 as k

    def boom(*a, **kw):
        raise RuntimeError("something\nunexpected")

    monkeypatch.setattr(k, "_plot", boom)
    code, _, err = run(["kf2x2", "--frames", 50, "--out", tmp_path], capsys)
    assert_one_line(err.replace("internal error", "internal-error"), code, 3,
                    "RuntimeError: something unexpected")


def test_library_warnings_are_one_line_each(capsys):
    import warnings

    from navgate.cli.warnings import warning_handler

    with warning_handler("navgate x"):
        np.log(np.zeros(2))  # RuntimeWarning: divide by zero
        np.log(np.zeros(2))  # the same warning again: shown once
        warnings.warn("a library\nsays\nthis", UserWarning, stacklevel=1)
        warnings.warn("use @ instead of *", PendingDeprecationWarning, stacklevel=1)
        warnings.warn("old API", DeprecationWarning, stacklevel=1)
        import logging

        logging.getLogger("rasterio._env").warning("CPLE_AppDefined in\nsomething")
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 3, err
    assert all(ln.startswith("navgate x: warning: ") for ln in lines)
    assert "divided by zero" in lines[0]


def test_fly_with_ungeoreferenced_dem_prints_no_library_lines(tmp_path, capsys):
    path = tmp_path / "plain.tif"
    with rasterio.open(path, "w", driver="GTiff", width=50, height=50, count=1,
                       dtype="float32") as d:
        d.write(np.full((50, 50), 300.0, dtype="float32"), 1)
    code, _, err = run(["fly", "--dem", path, "--out", tmp_path / "o"], capsys)
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert all(ln.startswith("navgate fly: ") for ln in lines), err
    assert sum(": error: " in ln for ln in lines) == 1


def test_ahrs_streaming_equals_in_memory(tmp_path, capsys, monkeypatch):
    """Blocks of 97 rows (gaps, held magnetometer and skipped rows across block edges) give
    byte-identical output to one block, and the same as the in-memory API."""
    import navgate.sim.imu_log as imu_log
    from navgate.sim.imu_log import read_imu_csv
    from navgate.systems.attitude.estimate import estimate_attitude

    rng = np.random.default_rng(3)
    n = 1000
    t = np.arange(n) / 100.0
    t[500:] += 2.0  # a gap
    src = imu_csv(tmp_path / "log.csv", n=n, t=t, gyro=rng.normal(0, 0.2, (n, 3)))
    lines = src.read_text().splitlines()
    for k in range(3, n, 4):  # 25 Hz magnetometer in a 100 Hz log
        cells = lines[k].split(",")
        lines[k] = ",".join(cells[:7] + ["", "", ""])
    lines[301] = "garbage"
    src.write_text("\n".join(lines) + "\n")
    outs = {}
    for rows in (97, 100_000):
        monkeypatch.setattr(imu_log, "CHUNK_ROWS", rows)
        code, _, err = run(["ahrs", src, "--out", tmp_path / f"o{rows}.csv", "--quiet"], capsys)
        assert code == 0, err
        outs[rows] = (tmp_path / f"o{rows}.csv").read_bytes()
    assert outs[97] == outs[100_000]
    res = estimate_attitude(read_imu_csv(src), "mahony", kp=1.0, ki=0.1)
    data = np.loadtxt(tmp_path / "o97.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(data[:, 1:5], res.q, atol=5e-10)  # %.9f output
    assert res.gaps == 1


# ---------------------------------------------------------------------------------------------
# 4. plausibility


def ahrs_table(tmp_path, capsys, path, *extra):
    import contextlib

    # without --out, ahrs writes navgate-out/ahrs/summary.json: in tmp_path, not the tree
    with contextlib.chdir(tmp_path):
        code, out, err = run(["ahrs", path, *extra], capsys)
    return code, out, err


def row_value(out, label):
    for line in out.splitlines():
        if label in line:
            return line.split("│")[-2].strip()
    raise AssertionError(f"{label!r} not in {out}")


@pytest.mark.parametrize("value", ["1e30", "1e200", "-1e300"])
def test_impossible_readings_are_screened_and_counted(value, tmp_path, capsys):
    src = imu_csv(tmp_path / "log.csv", n=1000)
    lines = src.read_text().splitlines()
    lines[400] = lines[400].replace(lines[400].split(",")[1], value, 1)
    lines[600] = ",".join(lines[600].split(",")[:5] + [value] + lines[600].split(",")[6:])
    src.write_text("\n".join(lines) + "\n")
    code, out, err = ahrs_table(tmp_path, capsys, src)
    assert code == 0, err
    assert row_value(out, "implausible rows") == "2"
    final = [float(v) for v in row_value(out, "final roll").split()[::2][:3]]
    assert max(abs(final[0]), abs(final[1])) < 0.5  # still level


def test_huge_gain_is_rejected(tmp_path, capsys):
    src = imu_csv(tmp_path / "log.csv")
    for kp in ("1e300", "150"):
        code, _, err = ahrs_table(tmp_path, capsys, src, "--kp", kp)
        assert_one_line(err, code, 2, "kp * dt")


def test_time_gap_restarts_the_filter(tmp_path, capsys):
    """A 100 s gap in a stationary level log with a gyro bias: integrating across it would
    turn 0.02 rad/s into 115 deg of roll; restarting keeps the attitude level."""
    n = 2000
    t = np.arange(n) / 100.0
    t[1000:] += 100.0
    gyro = np.tile([0.02, 0.0, 0.0], (n, 1))
    src = imu_csv(tmp_path / "log.csv", n=n, t=t, gyro=gyro, mag=False)
    code, out, err = ahrs_table(tmp_path, capsys, src, "--ki", "0")
    assert code == 0, err
    assert row_value(out, "time gaps") == "1"
    roll = float(row_value(out, "final roll").split("/")[0])
    assert abs(roll) < 2.0  # steady state of a 0.02 rad/s bias against kp = 1: 1.15 deg


@pytest.mark.parametrize("scale, unit", [(1e3, "milliseconds"), (1e6, "microseconds")])
def test_timestamps_not_in_seconds_are_named(scale, unit, tmp_path, capsys):
    src = imu_csv(tmp_path / "log.csv", t_scale=scale)
    code, _, err = ahrs_table(tmp_path, capsys, src)
    assert_one_line(err, code, 2, unit)


def test_deg_per_s_under_rad_per_s_header(tmp_path, capsys):
    n = 600
    t = np.arange(n) / 100.0
    gyro = np.column_stack([90 * np.sin(t), 60 * np.cos(t), np.zeros(n)])  # deg/s values
    src = imu_csv(tmp_path / "log.csv", n=n, gyro=gyro)
    code, _, err = ahrs_table(tmp_path, capsys, src)
    assert_one_line(err, code, 2, "deg/s")
    code, out, err = ahrs_table(tmp_path, capsys, src, "--gyro-unit", "deg/s")
    assert code == 0, err


def test_no_mag_keeps_rows_and_slow_magnetometer_is_held(tmp_path, capsys):
    """A 25 Hz magnetometer in a 100 Hz log: all 3000 rows are used, 2250 hold the previous
    magnetometer sample; --no-mag keeps every row too."""
    src = imu_csv(tmp_path / "log.csv", n=3000)
    lines = src.read_text().splitlines()
    for k in range(1, 3001):
        if (k - 1) % 4:
            lines[k] = ",".join(lines[k].split(",")[:7] + ["", "", ""])
    src.write_text("\n".join(lines) + "\n")
    code, out, err = ahrs_table(tmp_path, capsys, src)
    assert code == 0, err
    assert row_value(out, "samples") == "3000" and "held over 2250 rows" in out
    code, out, err = ahrs_table(tmp_path, capsys, src, "--no-mag")
    assert code == 0, err
    assert row_value(out, "samples") == "3000" and row_value(out, "skipped rows") == "0"


def test_kf2x2_overflow_fails_unless_accepted(tmp_path, capsys):
    code, out, err = run(["kf2x2", "--n", 12, "--frac", 4, "--frames", 400, "--out",
                          tmp_path / "a"], capsys)
    assert_one_line(err.split("\n", 1)[-1] if err.startswith("wrote") else err, code, 2,
                    "overflows in")
    assert "OVERFLOW" in out
    code, out, err = run(["kf2x2", "--n", 12, "--frac", 4, "--frames", 400, "--out",
                          tmp_path / "b", "--accept-overflow", "--quiet"], capsys)
    assert code == 0, err
    s = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert s["overflow_frames"] > 0 and s["overflow_accepted"] is True


@pytest.mark.parametrize("n, frac", [(8, 2), (8, 1), (7, 2)])
def test_kf2x2_word_length_range(n, frac, tmp_path, capsys):
    code, _, err = run(["kf2x2", "--n", n, "--frac", frac, "--out", tmp_path], capsys)
    line = assert_one_line(err, code, 2, "must be in [")
    assert "32]" in line


@pytest.mark.parametrize("scale", [1000.0, 1e30])
def test_dem_not_in_metres(scale, tmp_path, capsys):
    path = tmp_path / "scaled.tif"
    transform = from_origin(-84.3, 36.7, 1 / 1200, 1 / 1200)
    rng = np.random.default_rng(0)
    with rasterio.open(path, "w", driver="GTiff", width=400, height=400, count=1,
                       dtype="float64", crs="EPSG:4326", transform=transform) as d:
        d.write(rng.uniform(200, 600, (400, 400)) * scale, 1)
    code, _, err = run(["fly", "--dem", path, "--out", tmp_path / "o"], capsys)
    assert_one_line(err, code, 2, "not terrain heights in metres")


def test_non_finite_summary_is_not_exit_0(tmp_path, capsys, monkeypatch):
    import navgate.systems.ins_trn.ps.flight as flight

    original = flight.FlightResult.summary if hasattr(flight, "FlightResult") else None
    result_cls = None
    for obj in vars(flight).values():
        if isinstance(obj, type) and hasattr(obj, "summary") and obj.__module__ == flight.__name__:
            result_cls = obj
    assert result_cls is not None
    original = result_cls.summary

    def nan_summary(self):
        s = original(self)
        s["ins_only"]["rms_horizontal_error_m"] = float("nan")
        return s

    monkeypatch.setattr(result_cls, "summary", nan_summary)
    code, _, err = run(["fly", "--duration", 20, "--no-trn", "--out", tmp_path, "--quiet"],
                       capsys)
    assert_one_line(err, code, 2, "non-finite")


def test_every_command_routes_errors_through_one_line():
    """Every registered command is a click command with --help (so main() owns its errors)."""
    for name in COMMANDS:
        assert isinstance(command(name), click.Command)


def test_report_parallel_blocks_progress_and_order(tmp_path, capsys, monkeypatch):
    """``report -j 3`` (synthesis replaced by a stub): one progress line per block on stderr,
    the table on stdout in registry order, the same table as ``-j 1``."""
    import navgate.hw.flow as flow
    from navgate.hw.blocks import all_blocks

    monkeypatch.setattr(flow, "synthesize", lambda text, name, *a: {
        "lut": len(name), "ff": 1, "dsp": 0, "carry4": 0, "bram36": 0})
    monkeypatch.setattr(flow, "emit_verilog", lambda component, name: f"module {name};")
    monkeypatch.setattr(flow, "describe_block", lambda component, name, description, text: {
        "block": name, "latency_cycles": 1, "throughput": "1"})
    tables = {}
    for jobs in (1, 3):
        monkeypatch.setenv("NAVGATE_CACHE_DIR", str(tmp_path / f"cache{jobs}"))  # both cold
        code, out, err = run(["report", "-j", jobs, "--out", tmp_path / f"r{jobs}.md"], capsys)
        assert code == 0, err
        names = list(all_blocks())
        assert sum(" done (" in ln for ln in err.splitlines()) == len(names)
        rows = [ln.split("|")[1].strip() for ln in out.splitlines()[2:] if ln.startswith("|")]
        assert rows == names
        # under the table: which blocks came from the synth cache (none: a fresh cache root)
        assert f"Synthesised in this run: {len(names)} of {len(names)} blocks" in out
        assert (tmp_path / f"r{jobs}.md").read_text() == out
        tables[jobs] = out
    assert tables[1] == tables[3]


def test_fpga_sim_refuses_ideal_sensors_and_reports_simulation_failures(tmp_path, capsys,
                                                                       monkeypatch):
    """``--engine fpga-sim`` needs the IMU's int16 words (one line, exit 2, before any
    simulation); a co-simulation that fails mid-flight is one line too, not a traceback."""
    code, _, err = run(["fly", "--engine", "fpga-sim", "--ideal-sensors", "--duration", "5",
                        "--out", tmp_path / "a"], capsys)
    assert_one_line(err, code, needle="--ideal-sensors")
    assert not (tmp_path / "a").exists()
    from navgate.systems.ins_trn.ps import fpga_sim
    def broken(self, setup, **kw):
        raise fpga_sim.FpgaSimError("native model: wedged by an earlier timeout")

    monkeypatch.setattr(fpga_sim.FpgaSimEngine, "__init__", broken)
    code, _, err = run(["fly", "--engine", "fpga-sim", "--duration", "5", "--quiet",
                        "--out", tmp_path / "b"], capsys)
    assert_one_line(err, code, needle="co-simulation failed")
    assert not (tmp_path / "b").exists()
