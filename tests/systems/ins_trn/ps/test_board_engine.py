"""The ``board`` engine without a board (issue 27): its whole code path - DevMemBus addressing,
access-by-access register traffic, the polled interrupt, the DMA buffer read through a second
DevMemBus - over the stand-in (the Verilated ``ins_trn_top`` with its sensor emulators behind
the native AXI server, seen through the word window DevMemBus maps) equals the fp32 engine
bit for bit, and so ``fpga-sim`` (test_fpga_sim.py); ``/dev/mem`` itself through a file-backed
map; and every way the board can be unusable is one line, exit 2, with bounded waits."""

from __future__ import annotations

import json
import os
import time

import numpy as np
import pytest

from navgate.cli import main
from navgate.hw.bus import DevMemBus
from navgate.systems.ins_trn.pl.registers import BASE_ADDRESS, ID_VALUE, register_map
from navgate.systems.ins_trn.ps import board_engine as B
from navgate.systems.ins_trn.ps import flight
from navgate.systems.ins_trn.ps.navigator import Navigator, engine_setup
from navgate.systems.ins_trn.ps.pl_interface import make_engine
from navgate.trn.dem import Dem

ID_OFFSET = register_map()["ID"].offset
#: the stand-in's flights (s): short, every bus access is a round trip to the native model
DURATION = 2.0


def _memory(tmp_path, id_value: int | None = None, base: int = BASE_ADDRESS):
    """A sparse file standing for physical memory up to ``base`` + 8 KiB, the ID register's
    word at ``base`` + 0x3C when ``id_value`` is given."""
    path = tmp_path / "mem"
    with open(path, "wb") as f:
        f.truncate(base + 0x2000)
        if id_value is not None:
            f.seek(base + ID_OFFSET)
            f.write(id_value.to_bytes(4, "little"))
    return path


def test_devmem_bus_maps_the_word_at_base_plus_offset(tmp_path):
    path = _memory(tmp_path)
    bus = DevMemBus(BASE_ADDRESS, 0x1000, str(path))
    bus.write(ID_OFFSET, ID_VALUE)
    bus.write(0xFFC, 0x1234_5678)
    bus.write(0x100, -1)  # a 32-bit word: the value masked
    assert bus.read(ID_OFFSET) == ID_VALUE and bus.read(0x100) == 0xFFFF_FFFF
    for offset in (0x1000, 2, -4):
        with pytest.raises(ValueError, match="not a word inside"):
            bus.read(offset)
    bus.close()
    with open(path, "rb") as f:
        f.seek(BASE_ADDRESS - 0x1000)
        raw = f.read(0x3000)  # the page before the map, the map, the page after
    at = 0x1000
    assert raw[at + ID_OFFSET:at + ID_OFFSET + 4] == b"GVAN"  # 'NAVG', little-endian
    assert raw[at + 0xFFC:at + 0x1000] == bytes.fromhex("78563412")
    assert raw[at + 0x100:at + 0x104] == b"\xff" * 4
    assert raw.count(b"\0") == len(raw) - 12  # nothing else written
    # the next page is another map: its word 0 is the file's word at base + 0x1000
    nxt = DevMemBus(BASE_ADDRESS + 0x1000, 0x1000, str(path))
    nxt.write(0, 7)
    nxt.close()
    with open(path, "rb") as f:
        f.seek(BASE_ADDRESS + 0x1000)
        assert f.read(4) == b"\x07\0\0\0"
    with pytest.raises(ValueError, match="page aligned"):
        DevMemBus(BASE_ADDRESS + 4, 0x1000, str(path))


@pytest.fixture(scope="module")
def standin():
    with B.open_board(B.BoardSettings(bus="verilator")) as board:
        yield board


def test_board_over_the_standin_equals_fp32_bit_for_bit(against_fp32, standin):
    """2 s of the default mission (altitude updates, a fix attempt with its profile DMA),
    then directed TRN updates (applied, gated, singular) and the integrity monitor's
    inflation."""
    stream, cfg, run, engs = against_fp32.fly("board", DURATION, board=standin)
    eng = engs["board"]
    hw = run.hardware
    assert hw["board_bus"] == "verilator"
    assert hw["profile_dmas"] == len(run.fixes) == 1
    assert hw["update_interrupts"] == eng.interrupts > 40  # altitude updates, each polled
    assert hw["interrupt_polls"] >= eng.interrupts
    assert eng.samples == eng.propagations == round(DURATION * 400)
    assert eng.baro_samples == int(np.sum(stream.baro_status == 0))
    assert eng.lidar_frames == stream.ranger_range.size > 15
    # every access went through DevMemBus's word window, one round trip each
    assert standin.bus._words.accesses > 10 * eng.samples
    against_fp32.directed_updates(engs, "board")


def test_a_second_flight_on_the_same_board_counts_from_where_the_fabric_stands(standin):
    """A board keeps running between flights: the sample counters do not start at zero.
    The engine resets the sequencer and counts from the counters it finds: two flights in a
    row on one board each equal fp32."""
    regs = standin.regs
    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=0.5, seed=2)
    _, _, stream = flight.record_stream(dem, cfg)

    def run(name, **options):
        eng = make_engine(name, engine_setup(stream.header, cfg), **options)
        return Navigator(eng, cfg, t0=stream.header["t0"], dem=dem, use_trn=True).run(stream)
    want = run("fp32")
    for _ in range(2):
        before = regs.read("SAMPLE_COUNT")
        got = run("board", board=standin)
        assert np.array_equal(want.nav, got.nav) and np.array_equal(want.sigma, got.sigma)
        assert regs.read("SAMPLE_COUNT") == before + 200  # the IMU's words, never reset
        assert regs.read_fields("ENG_STATUS")["propagations"] == 200  # reset at set-up
    assert before == regs.read("SAMPLE_COUNT") - 200 >= 200


class Ran:
    """A ``navgate`` command run in this process through its entry point (one-line errors
    and exit codes as a user sees them)."""

    def __init__(self, capsys, args):
        try:
            main(list(args))
            self.exit_code = 0
        except SystemExit as exit_:
            self.exit_code = exit_.code
        captured = capsys.readouterr()
        self.stderr, self.output = captured.err, captured.out + captured.err


def _fly(tmp_path, capsys, *args, name="out"):
    out = tmp_path / name
    return Ran(capsys, ["fly", "--duration", "1", "--no-trn", "--quiet", "--out", str(out),
                        *map(str, args)]), out


def test_fly_engine_board_over_the_standin_equals_fp32(tmp_path, capsys):
    board, out_b = _fly(tmp_path, capsys, "--engine", "board", "--board-bus", "verilator", name="b")
    assert board.exit_code == 0, board.output
    fp32, out_f = _fly(tmp_path, capsys, "--engine", "fp32", name="f")
    assert fp32.exit_code == 0, fp32.output
    assert (out_b / "trajectory.csv").read_bytes() == (out_f / "trajectory.csv").read_bytes()
    summary = json.loads((out_b / "summary.json").read_text())
    assert summary["engine"] == "board"


def _one_line_exit_2(result, needle: str):
    assert result.exit_code == 2, result.output
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("navgate fly: error: "), result.output
    assert needle in lines[0], result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize("args, needle", [
    (["--board-bus", "devmem"], "goes with --engine board"),
    (["--engine", "board", "--board-base", "0x1000"], "outside the Zynq's GP ports"),
    (["--engine", "board", "--board-base", "0x40000800"], "not page aligned"),
    (["--engine", "board", "--board-base", "zz"], "is not an address"),
    (["--engine", "board", "--board-dma", "0x3FF00004"], "16-byte aligned"),
    (["--engine", "board", "--board-irq", "edge"], "give poll or a UIO device"),
    (["--engine", "board", "--board-bus", "pynq", "--board-mem", "/dev/mem"],
     "--board-mem goes with --board-bus devmem"),
])
def test_bad_board_options_are_one_line(tmp_path, capsys, args, needle):
    result, out = _fly(tmp_path, capsys, *args)
    _one_line_exit_2(result, needle)
    assert not out.exists()


def test_no_dev_mem_no_pynq_wrong_base_one_line(tmp_path, capsys):
    missing = tmp_path / "no-such-mem"
    result, _ = _fly(tmp_path, capsys, "--engine", "board", "--board-mem", missing)
    _one_line_exit_2(result, f"no {missing} on this machine")
    try:
        import pynq  # noqa: F401
    except ImportError:
        result, _ = _fly(tmp_path, capsys, "--engine", "board", "--board-bus", "pynq")
        _one_line_exit_2(result, "needs the pynq package")
    # memory where no bank answers (reads 0), and a bank whose ID is not seed 000's
    for id_value, shown in ((None, "0x00000000"), (0x1234_5678, "0x12345678")):
        mem = _memory(tmp_path, id_value)
        result, _ = _fly(tmp_path, capsys, "--engine", "board", "--board-mem", mem)
        _one_line_exit_2(result, f"ID reads {shown}, the register map says 0x4E415647")
    # the stand-in at a wrong base address: nothing there either
    result, _ = _fly(tmp_path, capsys, "--engine", "board", "--board-bus", "verilator",
                     "--board-base", "0x40010000")
    _one_line_exit_2(result, "no ins_trn register bank at --board-base 0x40010000")


def test_a_bank_that_never_counts_is_a_bounded_wait_and_one_line(tmp_path, capsys):
    """The right ID but a fabric that does nothing (a file): the first wait for the IMU's
    samples runs out of reads, the flight stops with one line."""
    mem = _memory(tmp_path, ID_VALUE)
    start = time.monotonic()
    result, out = _fly(tmp_path, capsys, "--engine", "board", "--board-mem", mem)
    _one_line_exit_2(result, "--engine board: the board failed: ENG_STATUS")
    assert "reads" in result.output and time.monotonic() - start < 120
    assert not out.exists()
    mem = _memory(tmp_path, ID_VALUE)
    result, _ = _fly(tmp_path, capsys, "--engine", "board", "--board-mem", mem,
                     "--board-irq", tmp_path / "uio9")
    _one_line_exit_2(result, f"--board-irq {tmp_path / 'uio9'}: No such file")


def test_unloaded_pl_no_permission_bus_error_and_stall_are_board_errors(tmp_path, monkeypatch):
    mem = _memory(tmp_path, ID_VALUE)
    state = tmp_path / "state"
    for word in ("unknown", "write init"):
        state.write_text(word + "\n")
        with pytest.raises(B.BoardError, match=f"PL is not configured .*'{word}'.*bitstream"):
            B.open_board(B.BoardSettings(mem=str(mem), fpga_state=str(state)))
    state.write_text("operating\n")
    with B.open_board(B.BoardSettings(mem=str(mem), fpga_state=str(state))) as board:
        assert board.regs.read("ID") == ID_VALUE
        assert board.dma.address == B.DMA_ADDRESS
    # memory that ends before the DMA buffer (a kernel that refuses to map it does the same)
    small = tmp_path / "small"
    with open(small, "wb") as f:
        f.truncate(BASE_ADDRESS + 0x1000)
        f.seek(BASE_ADDRESS + ID_OFFSET)
        f.write(ID_VALUE.to_bytes(4, "little"))
    with pytest.raises(B.BoardError, match="cannot map the profile DMA's buffer at --board-dma "
                                           "0x40001000"):
        B.open_board(B.BoardSettings(mem=str(small), dma=BASE_ADDRESS + 0x1000))
    # a read on a map whose memory went away: SIGBUS in the probe's child, not here
    gone = tmp_path / "gone"
    gone.write_bytes(bytes(0x2000))

    def vanishing():
        bus = DevMemBus(0x1000, 0x1000, str(gone))
        os.truncate(gone, 0)
        return bus
    with pytest.raises(B.BoardError, match="raised a bus error"):
        B._probe_id(vanishing, 0x1000)
    # a read that never returns: the child is killed after the probe's time
    monkeypatch.setattr(B, "PROBE_SECONDS", 0.3)

    def stalling():
        time.sleep(60)
    start = time.monotonic()
    with pytest.raises(B.BoardError, match=r"did not return in 0.3 s: the bus stalls"):
        B._probe_id(stalling, BASE_ADDRESS)
    assert time.monotonic() - start < 10
    # /dev/mem that root may not open (this process may be root: the refusal is simulated)
    real_open = os.open

    def refuse(path, *args):
        if str(path) == str(mem):
            raise PermissionError(13, "Permission denied")
        return real_open(path, *args)
    monkeypatch.setattr(B.os, "open", refuse)
    with pytest.raises(B.BoardError, match=f"no permission to open {mem}: run as root"):
        B.open_board(B.BoardSettings(mem=str(mem)))


class _Counting:
    """A bus whose ENG_STATUS counts on by itself (live sensors): +3 samples per read."""

    def __init__(self, start: int, busy: int = 0):
        self.value, self.busy, self.reads = start, busy, 0

    def read(self, offset):
        assert offset == register_map()["ENG_STATUS"].offset
        self.reads += 1
        self.value = (self.value + 3) & 0xFFFFFF
        return self.value << 8 | self.busy

    def write(self, offset, value):
        raise AssertionError("no writes")


def test_live_sensors_count_past_the_sample_the_ps_waits_for():
    from navgate.hw.regmap import Registers, RegisterTimeout
    from navgate.systems.ins_trn.ps.pl_registers import wait_count

    # the fabric passes 100 without ever showing it: reached or passed ends the wait
    bus = _Counting(90)
    got = wait_count(Registers(register_map(), bus), "ENG_STATUS", "propagations", 100, True,
                     limit=50, busy=0)
    assert got.value >> 8 == 102 and bus.reads == 4
    # across the 24-bit wrap: 0xFFFFFC, 0xFFFFFF (not yet), then 2
    bus = _Counting(0xFFFFFC)
    got = wait_count(Registers(register_map(), bus), "ENG_STATUS", "propagations", 2, True,
                     limit=50, busy=0)
    assert got.value >> 8 == 2 and bus.reads == 2
    # the engine still busy: bounded, then a timeout naming the counter
    bus = _Counting(90, busy=1)
    with pytest.raises(RegisterTimeout, match="ENG_STATUS.propagations did not reach 100 "
                                              "in 20 reads"):
        wait_count(Registers(register_map(), bus), "ENG_STATUS", "propagations", 100, True,
                   limit=20, busy=0)
    assert bus.reads == 20


def test_uio_interrupt_unmasks_waits_and_acknowledges(monkeypatch):
    """The UIO protocol (Linux's uio driver): write 1 to unmask, the interrupt makes the
    device readable, read the 4-byte count; here a pseudo-terminal in raw mode stands for
    /dev/uioN, its master side for the kernel."""
    import threading
    import tty

    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    monkeypatch.setattr(B, "UIO_SECONDS", 0.3)
    irq = B._UioInterrupt(path)
    try:
        raiser = threading.Timer(0.1, os.write, (master, (7).to_bytes(4, "little")))
        raiser.start()
        start = time.monotonic()
        irq.wait()
        assert 0.05 < time.monotonic() - start < 0.3
        assert os.read(master, 16) == b"\x01\0\0\0"  # unmasked before waiting
        with pytest.raises(B.BoardError, match=f"no interrupt on {path} within 0.3 s"):
            irq.wait()  # nothing comes: bounded
        raiser.join()
    finally:
        irq.close()
        os.close(slave)
        os.close(master)


def test_replay_refuses_the_board_and_the_board_has_its_hardware_line(tmp_path, capsys):
    from navgate.cli.console import hardware_line

    log = tmp_path / "flight.log"
    log.write_bytes(b"")
    result = Ran(capsys, ["replay", str(log), "--engine", "board", "--out", str(tmp_path / "o")])
    assert result.exit_code == 2 and "replay the log with --engine fpga-sim" in result.stderr
    line = hardware_line({"board_bus": "devmem", "update_interrupts": 1500, "profile_dmas": 120,
                          "baro_samples_through_pins": 15000,
                          "ranger_frames_through_pins": 6000, "interrupt_polls": 4000})
    assert line == ("the board's fabric over devmem: 1,500 update interrupts, 120 profile "
                    "DMAs, 15,000 barometer samples and 6,000 ranger frames through the pins")


@pytest.mark.slow
def test_board_over_the_standin_equals_fpga_sim_20s_flight():
    """20 s of the default mission INS+TRN through the stand-in and through fpga-sim: every
    logged word, update and fix decision equal, an applied TRN fix among them."""
    from navgate.systems.ins_trn.ps.navigator import navigate

    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=20.0, seed=1)
    _, _, stream = flight.record_stream(dem, cfg)
    sim = navigate(stream, cfg, engine="fpga-sim", dem=dem, use_trn=True)
    with B.open_board(B.BoardSettings(bus="verilator")) as board:
        brd = navigate(stream, cfg, engine="board", dem=dem, use_trn=True,
                       engine_options={"board": board})
    assert np.array_equal(sim.nav, brd.nav) and np.array_equal(sim.sigma, brd.sigma)
    assert np.array_equal(sim.p_ne, brd.p_ne)
    assert sim.accepted == brd.accepted and brd.accepted["trn"] >= 1
    assert [f["applied"] for f in sim.fixes] == [f["applied"] for f in brd.fixes]
    assert brd.hardware["profile_dmas"] == len(brd.fixes) == 4
