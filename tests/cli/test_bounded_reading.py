"""Bounded reading (issue 31): every reader of the command line stops at a size or a time
limit with one line and exit 2, never a hang; absurd option values that would make a run
endless are refused; the first Ctrl-C stops ``navgate report``.

Hangs are guarded by subprocess timeouts (a regression fails by timing out, not by hanging
the suite); the limits themselves are module constants, lowered here where the real ones
would take seconds."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from navgate.cli import inputs

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="FIFOs and /dev/zero")


def navgate(*args, timeout=60, **kw):
    return subprocess.run([sys.executable, "-m", "navgate.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, **kw)


def one_line(proc, needle=""):
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "internal error" not in proc.stderr and needle in lines[0], lines[0]
    return lines[0]


def test_decode_dev_zero_stops_at_the_size_limit(tmp_path):
    start = time.perf_counter()
    proc = navgate("tinykalman", "decode", "/dev/zero", "--out", tmp_path / "o", timeout=30)
    line = one_line(proc, "64 MiB")
    assert "/dev/zero" in line
    assert time.perf_counter() - start < 30
    assert not (tmp_path / "o").exists()


def test_replay_dev_zero_and_directory_are_refused(tmp_path):
    one_line(navgate("replay", "/dev/zero", "--out", tmp_path / "o", timeout=30),
             "not a regular file")
    one_line(navgate("replay", tmp_path, "--out", tmp_path / "o", timeout=30))
    assert not (tmp_path / "o").exists()


def test_fifo_without_writer(tmp_path, navgate_run, monkeypatch):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    # fly --record into a FIFO with no reader: refused before the flight
    code, _, err = navgate_run(["fly", "--duration", 5, "--no-trn", "--quiet", "--record", fifo,
                                "--out", tmp_path / "o"])
    assert code == 2 and "not a regular file" in navgate_run.one_line(err)
    # replay and tinykalman run of a FIFO: refused before opening it (open would block)
    code, _, err = navgate_run(["replay", fifo, "--out", tmp_path / "o"])
    assert code == 2 and "not a regular file" in navgate_run.one_line(err)
    code, _, err = navgate_run(["tinykalman", "run", fifo, "--out", tmp_path / "o"])
    assert code == 2 and "not a regular file" in navgate_run.one_line(err)
    # decode reads a FIFO, but waits for a writer only up to its time limit
    import navgate.cli.tinykalman as tk

    monkeypatch.setattr(tk, "MAX_READ_S", 0.3)
    start = time.perf_counter()
    code, _, err = navgate_run(["tinykalman", "decode", fifo, "--out", tmp_path / "o"])
    assert code == 2 and "no end of input after 0.3 s" in navgate_run.one_line(err)
    assert time.perf_counter() - start < 5
    assert not (tmp_path / "o").exists()


def test_read_bounded_reads_a_fifo_that_ends(tmp_path):
    """A FIFO whose writer ends is read whole (the limits are for endless inputs only)."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    payload = bytes(range(256)) * 1000
    writer = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import time; time.sleep(0.2)
        with open({str(fifo)!r}, "wb") as fh:
            fh.write(bytes(range(256)) * 1000)
    """)])
    try:
        assert inputs.read_bounded(fifo, 1 << 20, 10.0) == payload
    finally:
        writer.wait(timeout=10)
    # the size limit of a regular file is checked from its size, before reading
    big = tmp_path / "big.bin"
    big.write_bytes(b"\0" * 2048)
    with pytest.raises(inputs.CliError, match="more than the"):
        inputs.read_bounded(big, 1024)
    assert inputs.read_bounded(big, 2048) == b"\0" * 2048


@pytest.mark.parametrize("seconds", ["inf", "1e300", "nan", "86401"])
def test_decode_serial_endless_capture_is_refused(seconds, navgate_run, tmp_path):
    code, _, err = navgate_run(["tinykalman", "decode", "--serial", "loop://", "--seconds",
                                seconds, "--out", tmp_path / "o"])
    line = navgate_run.one_line(err)
    assert code == 2 and "--seconds" in line, line


def test_campaign_seed_and_run_caps(navgate_run, tmp_path):
    start = time.perf_counter()
    for seeds, needle in (("0-1180591620717411303424", "more than 100000 seeds"),
                          ("1180591620717411303424", "below 2**63"),
                          ("0-99999,100000-100001", "more than 100000 seeds")):
        code, _, err = navgate_run(["campaign", "--seeds", seeds, "--out", tmp_path / "o"])
        assert code == 2 and needle in navgate_run.one_line(err), err
    # within the seed cap, but seeds x configurations over the run cap
    code, _, err = navgate_run(["campaign", "--seeds", "0-99999", "--trn", "pmf", "--trn",
                                "tercom", "--out", tmp_path / "o"])
    line = navgate_run.one_line(err)
    assert code == 2 and "200,000 runs" in line, line
    assert time.perf_counter() - start < 20  # nothing enumerated or started


def test_record_log_lines_are_bounded(tmp_path):
    """A record log of one endless line (zeros, binary) or an over-long record line is read
    in bounded pieces: the header is an error, a record is a counted bad record."""
    from navgate.systems.ins_trn.ps import records

    zeros = tmp_path / "zeros.log"
    zeros.write_bytes(b"\0" * (1 << 20))
    with pytest.raises(records.LogError, match="not a navgate record log"):
        records.read_log(zeros)
    log = tmp_path / "long.log"
    good = [f"I,{k / 400!r},0,0,0,0,0,-16000" for k in range(1, 5)]
    log.write_text("\n".join([records.MAGIC, 'H {"ideal": false}', good[0],
                              "I," + "1" * 100_000, *good[1:]]) + "\n")
    stream = records.read_log(log)
    assert stream.n_imu == 4 and stream.bad_records == {"over-long record": 1}
    deep = tmp_path / "deep.log"
    deep.write_text(records.MAGIC + "\nH " + "[" * 100_000 + "]" * 100_000 + "\n")
    with pytest.raises(records.LogError, match="nested too deeply|not a JSON object"):
        records.read_log(deep)


REPORT_SCRIPT = """
import sys, time
from pathlib import Path
import navgate.hw.flow as flow
from navgate.hw import synth

started = Path(sys.argv[1])

def slow_build(name, out_dir, **kw):
    with open(started, "a") as fh:
        fh.write(name + "\\n")
    synth._run_tool("sleeper", "run", ["60"], out_dir, out_dir / "tool.log")
    raise AssertionError("not reached")

flow.build_block = slow_build
from navgate.cli import main
main(["report", "-j", "2"])
"""


def test_first_ctrl_c_stops_report(tmp_path):
    """The first SIGINT ends ``navgate report`` at once (exit 130): the running tool
    processes are killed and no queued block starts."""
    (tmp_path / "sleeper.py").write_text(
        "import time\n\ndef run(argv):\n    time.sleep(float(argv[0]))\n    return 0\n")
    started = tmp_path / "started.txt"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(tmp_path), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-c", REPORT_SCRIPT, str(started)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and (
                not started.exists() or len(started.read_text().split()) < 2):
            time.sleep(0.1)
        assert started.exists(), "the report never started a block"
        time.sleep(0.5)  # both tool processes running
        sent = time.monotonic()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)
        took = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err, err
    assert took < 10, took  # not the 60 s the tools would have taken
    assert len(started.read_text().split()) == 2  # no queued block started after the signal


def test_dem_inputs_that_are_not_files_are_refused(tmp_path, navgate_run):
    """A DEM is read by seeking: a FIFO (GDAL's open would block) or a device is one line,
    for every command that takes a DEM."""
    fifo = tmp_path / "dem.fifo"
    os.mkfifo(fifo)
    start = time.perf_counter()
    for args in (["fly", "--dem", fifo, "--duration", 5, "--out", tmp_path / "o"],
                 ["replay", tmp_path / "missing.log", "--dem", fifo],
                 ["campaign", "--seeds", "0", "--dem", fifo, "--out", tmp_path / "o"],
                 ["tiles", "split", fifo, "--into", "1x1", "--out", tmp_path / "o"],
                 ["trn-serve", "--tiles", fifo, "--listen", "tcp://127.0.0.1:0"]):
        code, _, err = navgate_run(args)
        line = navgate_run.one_line(err)
        assert code == 2, (args, err)
        assert "not a regular file or a directory" in line or "cannot read" in line, line
    assert time.perf_counter() - start < 30
    assert not (tmp_path / "o").exists()


def test_ahrs_fifo_waits_for_its_writer_only_so_long(tmp_path, navgate_run, monkeypatch):
    import threading

    monkeypatch.setattr(inputs, "FIFO_WAIT_S", 0.3)
    fifo = tmp_path / "imu.fifo"
    os.mkfifo(fifo)
    code, _, err = navgate_run(["ahrs", fifo])
    assert code == 2 and "no writer opened within 0.3 s" in navgate_run.one_line(err)
    with open(fifo, "wb"):  # the abandoned waiter gets its writer and lets go
        pass
    # a FIFO with a writer streams as a file does
    fifo = tmp_path / "imu2.fifo"
    os.mkfifo(fifo)
    n = 300
    rows = "\n".join(f"{k / 100:.2f},0,0,0,0,0,-9.80665" for k in range(n))
    text = "t,gx,gy,gz,ax,ay,az\n" + rows + "\n"
    writer = threading.Thread(target=lambda: fifo.write_text(text))
    monkeypatch.setattr(inputs, "FIFO_WAIT_S", 10.0)
    writer.start()
    code, out, err = navgate_run(["ahrs", fifo])
    writer.join(timeout=10)
    assert code == 0, err
    assert re.search(rf"samples\s*│\s*{n}\b", out), out  # every row came through the FIFO
