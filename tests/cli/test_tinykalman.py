"""``navgate tinykalman``: run (model and rtl engines) and decode (file, serial), outputs,
summary, and bad input."""

import json
import math
import sys
import types

import numpy as np
import pytest

from navgate.cli import main
from navgate.systems.tinykalman import model as tk
from navgate.systems.tinykalman.run import model_stream, words_from_imu

XIO = ("Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),"
       "Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g)")


def run_cli(args, capsys):
    code = 0
    try:
        main(["tinykalman", *map(str, args)])
    except SystemExit as exit_:
        code = exit_.code
    out = capsys.readouterr()
    return code, out.out, out.err


def write_log(path, n=40, roll_deg=30.0, plain=False):
    """Tilted by ``roll_deg`` about x, turning at 5 deg/s about x; x-io (g, deg/s, +1 g on z
    level) or plain FRD (m/s^2, rad/s, -g on z level)."""
    rng = np.random.default_rng(0)
    t = np.arange(n) * 0.01
    r = math.radians(roll_deg)
    acc = np.tile([0.0, math.sin(r), math.cos(r)], (n, 1)) + rng.normal(0, 0.002, (n, 3))
    gyro = np.tile([5.0, 0.0, 0.0], (n, 1))
    if plain:
        lines = ["t,gx,gy,gz,ax,ay,az"]
        for k in range(n):
            a = acc[k] * np.array([1, -1, -1]) * 9.80665
            g = np.radians(gyro[k]) * np.array([1, -1, -1])
            lines.append(",".join(f"{v:.9g}" for v in (t[k], *g, *a)))
    else:
        lines = [XIO] + [",".join(f"{v:.9g}" for v in (t[k], *gyro[k], *acc[k]))
                         for k in range(n)]
    path.write_text("\n".join(lines) + "\n")
    return acc * 9.80665, np.radians(gyro)


def test_model_run_outputs(tmp_path, capsys):
    log = tmp_path / "log.csv"
    acc, gyro = write_log(log)
    out = tmp_path / "o"
    code, _, err = run_cli([log, "--engine", "model", "--out", out, "--quiet"], capsys)
    assert code == 0, err
    stream = (out / "uart.bin").read_bytes()
    assert stream == model_stream(words_from_imu(acc, gyro))
    s = json.loads((out / "summary.json").read_text())
    assert s["samples"] == 40 and s["packets"] == 40 and s["uart_bytes"] == 240
    assert s["axes"] == "flu" and s["skipped_bytes"] == 0
    assert s["chip_timing_default"]["latency_cs_rise_to_start_bit"] == 45
    rows = (out / "roll_pitch.csv").read_text().splitlines()
    words = (out / "mpu6500_words.csv").read_text().splitlines()
    assert len(rows) == 41 and len(words) == 41
    assert words[1].split(",")[4] == str(round(acc[0, 2] / 9.80665 * 16384))  # az word
    # 40 samples of a 1/64 filter starting at 0: the estimate has moved toward +30 deg
    assert 0 < s["final_roll_deg"] < 30


def test_plain_frd_log_is_turned_into_the_parts_axes(tmp_path, capsys):
    log = tmp_path / "plain.csv"
    acc, gyro = write_log(log, plain=True)
    out = tmp_path / "p"
    code, _, err = run_cli([log, "--out", out, "--quiet"], capsys)
    assert code == 0, err
    assert (out / "uart.bin").read_bytes() == model_stream(words_from_imu(acc, gyro))


def test_rtl_engine_equals_model_byte_for_byte(tmp_path, capsys):
    log = tmp_path / "log.csv"
    write_log(log, n=25)
    code, _, err = run_cli([log, "--engine", "model", "--out", tmp_path / "m", "--quiet"],
                           capsys)
    assert code == 0, err
    code, _, err = run_cli([log, "--engine", "rtl", "--out", tmp_path / "r", "--quiet"], capsys)
    assert code == 0, err
    assert (tmp_path / "r" / "uart.bin").read_bytes() == (tmp_path / "m" / "uart.bin").read_bytes()
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["rtl"]["equal_to_model"] is True and s["rtl"]["who_am_i_failures"] == 0
    assert s["rtl"]["latency_cycles"] == [42] and s["rtl"]["variant"] == "parallel"


def test_rtl_engine_serial_variant_equals_model(tmp_path, capsys):
    """--variant serial: the bit-serial chip, same bytes, its own latency (2 + 1 + 731 clocks)."""
    log = tmp_path / "log.csv"
    write_log(log, n=8)
    code, _, err = run_cli([log, "--engine", "model", "--out", tmp_path / "m", "--quiet"],
                           capsys)
    assert code == 0, err
    code, _, err = run_cli([log, "--engine", "rtl", "--variant", "serial", "--out",
                            tmp_path / "r", "--quiet"], capsys)
    assert code == 0, err
    assert (tmp_path / "r" / "uart.bin").read_bytes() == (tmp_path / "m" / "uart.bin").read_bytes()
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["rtl"]["variant"] == "serial" and s["rtl"]["latency_cycles"] == [734]
    assert s["rtl"]["equal_to_model"] is True


def test_decode_file_resynchronises_and_counts(tmp_path, capsys):
    data = b"\x01\x02\xde" + tk.encode_packet(100, -200) + tk.encode_packet(-1, 1) + b"\xde\xad\x00"
    f = tmp_path / "cap.bin"
    f.write_bytes(data)
    out = tmp_path / "d"
    code, _, err = run_cli(["decode", f, "--out", out], capsys)
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text())
    assert s == {"source": str(f), "bytes": len(data), "packets": 2, "skipped_bytes": 3,
                 "trailing_bytes": 3}
    rows = (out / "roll_pitch.csv").read_text().splitlines()
    assert rows[1].split(",")[2:4] == ["100", "-200"]


@pytest.mark.parametrize("data", [b"", bytes(range(256)) * 4, b"\x00" * 1000])
def test_decode_without_a_packet_is_an_error_and_writes_nothing(data, tmp_path, capsys):
    f = tmp_path / "cap.bin"
    f.write_bytes(data)
    out = tmp_path / "d"
    out.mkdir()
    (out / "roll_pitch.csv").write_text("earlier results\n")
    code, _, err = run_cli(["decode", f, "--out", out], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"no TinyKalman packet in {len(data)} bytes" in err
    assert sorted(p.name for p in out.iterdir()) == ["roll_pitch.csv"]
    assert (out / "roll_pitch.csv").read_text() == "earlier results\n"


def test_decode_serial_with_pyserial(tmp_path, capsys, monkeypatch):
    stream = b"\x00" + b"".join(tk.encode_packet(k, -k) for k in range(5))

    class Port:
        def __init__(self):
            self.data = bytearray(stream)

        def read(self, n):
            chunk, self.data[:] = bytes(self.data[:7]), self.data[7:]
            return chunk

        def close(self):
            pass

    opened = {}

    def serial_for_url(url, baudrate, timeout):
        opened.update(url=url, baud=baudrate)
        return Port()

    fake = types.SimpleNamespace(serial_for_url=serial_for_url, SerialException=OSError)
    monkeypatch.setitem(sys.modules, "serial", fake)
    out = tmp_path / "s"
    code, _, err = run_cli(["decode", "--serial", "loop://", "--seconds", "0.05", "--out", out],
                           capsys)
    assert code == 0, err
    assert opened == {"url": "loop://", "baud": 9600}
    s = json.loads((out / "summary.json").read_text())
    assert s["packets"] == 5 and s["skipped_bytes"] == 1
    assert (out / "capture.bin").read_bytes() == stream


@pytest.mark.parametrize("args, text", [
    (["decode"], "exactly one of FILE or --serial"),
    (["decode", "x.bin", "--serial", "p"], "exactly one of FILE or --serial"),
    (["decode", "/nonexistent/x.bin"], "cannot read"),
    (["/nonexistent/log.csv"], "No such file"),
    (["log.csv", "--engine", "fpga"], "Invalid value"),
    (["log.csv", "--engine", "rtl", "--variant", "bitwise"], "Invalid value"),
    (["log.csv", "--variant", "serial"], "--variant chooses the gateware run of --engine rtl"),
    (["log.csv", "--engine", "model", "--sim", "amaranth"], "--sim chooses the gateware run"),
    (["log.csv", "--engine", "model", "--sim", "verilator", "--variant", "parallel"],
     "--sim and --variant choose the gateware run"),
])
def test_bad_input_is_one_line(args, text, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(args, capsys)
    assert code == 2 and text in err and len(err.strip().splitlines()) == 1, err


def test_serial_without_pyserial_is_a_clear_error(capsys, monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "serial", None)  # import fails
    code, _, err = run_cli(["decode", "--serial", "/dev/ttyUSB9", "--out", tmp_path / "x"],
                           capsys)
    assert code == 2 and "pyserial" in err


def test_dropped_rows_are_counted_in_the_summary(tmp_path, capsys):
    """Rows the IMU reader drops (a NaN, an impossible 1e300 m/s^2) are counted in summary.json
    and on the table (issue 31, round 2: an implausible row once vanished without a count)."""
    log = tmp_path / "imu.csv"
    write_log(log, plain=True)
    lines = log.read_text().splitlines()
    lines[5] = lines[5].rsplit(",", 1)[0] + ",1e300"
    lines[9] = lines[9].rsplit(",", 1)[0] + ",nan"
    log.write_text("\n".join(lines) + "\n")
    code, out, err = run_cli(["run", log, "--out", tmp_path / "o"], capsys)
    assert code == 0, err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert (s["samples"], s["skipped_rows"], s["implausible_rows"]) == (38, 1, 1)
    assert "1 / 1" in out


def test_time_gaps_are_counted_and_reported(tmp_path, capsys):
    """Steps over 5 sample periods (the reference ahrs's gaps) are counted: the chip assumes
    one fixed period and integrates across them."""
    log = tmp_path / "imu.csv"
    write_log(log, plain=True)
    lines = log.read_text().splitlines()
    for k, row in enumerate(lines[1:], 1):  # 0.5 s missing after sample 20, 0.1 s after 30
        t, rest = row.split(",", 1)
        shift = 0.5 * (k > 20) + 0.1 * (k > 30)
        lines[k] = f"{float(t) + shift:.9g},{rest}"
    log.write_text("\n".join(lines) + "\n")
    code, out, err = run_cli(["run", log, "--out", tmp_path / "o"], capsys)
    assert code == 0, err
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["time_gaps"] == 2 and s["largest_time_gap_s"] == pytest.approx(0.51)
    assert "time gaps" in out and "2 time gaps" in err
    write_log(log, plain=True)
    code, out, err = run_cli(["run", log, "--out", tmp_path / "p"], capsys)
    s = json.loads((tmp_path / "p" / "summary.json").read_text())
    assert code == 0 and s["time_gaps"] == 0 and "largest_time_gap_s" not in s
