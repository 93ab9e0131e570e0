"""Running the TinyKalman chip at pin level against its integer model.

The chip (:class:`~navgate.systems.tinykalman.top.TinyKalmanTop`) talks to a bit-level MPU-6500
(:class:`navgate.devices.mpu6500.Mpu6500Bus`) on its SPI pins and sends UART packets; the
testbench

* serves a stream of seven-word samples (one per burst) and optionally injects faults from a
  given sample on (``faults = {sample_index: fault}``),
* receives the UART line (here a cycle-sampled 8N1 receiver; in Verilator the ``cocotbext-uart``
  ``UartSink``, :mod:`navgate.systems.tinykalman.tb_cocotb`),
* derives what the chip read from the device's transaction log (bytes on the MISO line, faults
  included) and runs the integer model on it (:func:`expected_stream`), so the comparison is
  byte for byte over the whole stream,
* measures per sample the clocks from CS_N rising at the end of the burst to the packet's
  first start bit.

Two back ends: :func:`run_amaranth` (Amaranth's simulator, about 3,000 clocks/s: short runs)
and :func:`run_verilator` (the emitted Verilog of the top inside a small TinyTapeout-style
``tb`` wrapper, Verilator through cocotb; Python wakes up only on pin changes). Verilator
builds go through the shared harness's cache (:mod:`navgate.gateware.verify`).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from navgate.devices.mpu6500 import (
    BURST_LEN,
    REG,
    Mpu6500Bus,
    SpiTiming,
)
from navgate.nav import validate
from navgate.systems.tinykalman.model import PACKET_LEN, TinyKalman
from navgate.systems.tinykalman.top import TT_MODULE_NAME, TinyKalmanTop, min_sample_period

__all__ = ["SimConfig", "FAST", "RtlRun", "expected_stream", "run_amaranth", "run_verilator",
           "tb_wrapper_verilog"]

CLK_NS = 100  # 10 MHz


@dataclass(frozen=True)
class SimConfig:
    """Elaboration parameters of a simulated chip."""

    spi_div: int = 2
    baud_div: int = 4
    sample_period: int | None = None  #: default: the shortest legal one
    variant: str = "parallel"  #: "parallel" or "serial" (top.VARIANTS)

    @property
    def period(self) -> int:
        return self.sample_period or min_sample_period(self.spi_div, self.baud_div,
                                                       self.variant)

    def params(self) -> dict:
        return {"spi_div": self.spi_div, "baud_div": self.baud_div,
                "sample_period": self.period, "variant": self.variant}

    def top(self) -> TinyKalmanTop:
        return TinyKalmanTop(**self.params())


#: the shortened configuration of the default tests and the CLI's ``--engine rtl``: the SPI
#: clock at 2.5 MHz, 2.5 Mbaud, the shortest sample period; the data path is the same
FAST = SimConfig()


@dataclass
class RtlRun:
    uart: bytes
    cycles: int
    seconds: float
    latencies: list[int]  #: per packet: clocks from CS_N rising (burst end) to first start bit
    device: Mpu6500Bus | None = None
    framing_errors: int = 0
    extra: dict = field(default_factory=dict)


def expected_stream(log, n_samples: int | None = None) -> tuple[bytes, list[int]]:
    """The model's UART bytes for what the chip read, from an :class:`Mpu6500Bus` log.

    The chip runs WHO_AM_I then the burst every sample; the log holds both transactions with
    the bytes seen on MISO. Returns (bytes, WHO_AM_I values read)."""
    tk = TinyKalman()
    out = bytearray()
    whos = []
    pairs = [(log[k], log[k + 1]) for k in range(0, len(log) - 1, 2)]
    if n_samples is not None:  # (-1 once meant "all but the last")
        pairs = pairs[:validate.integer("n_samples", n_samples, 0)]
    for (a0, r0, b0), (a1, r1, b1) in pairs:
        if not (a0 == REG["WHO_AM_I"] and r0 and a1 == REG["ACCEL_XOUT_H"] and r1
                and len(b0) == 2 and len(b1) == 1 + BURST_LEN):
            raise ValueError(f"unexpected transaction pair {(a0, r0, len(b0))}, "
                             f"{(a1, r1, len(b1))}")
        whos.append(b0[1])
        out += tk.step(bytes(b1[1:]), who_am_i=b0[1])
    return bytes(out), whos


def _device(samples, timing, keep_log=True):
    return Mpu6500Bus(samples, timing=timing, keep_log=keep_log)


class _UartRx:
    """Cycle-sampled 8N1 receiver: samples each bit in its middle clock."""

    def __init__(self, baud_div: int):
        self.div = baud_div
        self.bytes = bytearray()
        self.starts: list[int] = []
        self.errors = 0
        self._t0 = None
        self._prev = 1

    def sample(self, cycle: int, tx: int) -> None:
        if self._t0 is None:
            if self._prev and not tx:
                self._t0 = cycle
            self._prev = tx
            return
        self._prev = tx
        k, r = divmod(cycle - self._t0, self.div)
        if r != self.div // 2:
            return
        if k == 0:
            self._bits = []
            if tx:
                self.errors += 1
                self._t0 = None
        elif k <= 8:
            self._bits.append(tx)
        else:
            if not tx:
                self.errors += 1
            self.bytes.append(sum(b << i for i, b in enumerate(self._bits)))
            self.starts.append(self._t0)
            self._t0 = None


def run_amaranth(samples, n_samples: int, config: SimConfig = FAST, *,
                 timing: SpiTiming | None = None, faults: dict | None = None,
                 max_cycles: int | None = None) -> RtlRun:
    """Run ``n_samples`` sample periods of the chip in Amaranth's simulator."""
    from amaranth.sim import Simulator

    n_samples = validate.positive_int("n_samples", n_samples)
    if isinstance(samples, (list, tuple, np.ndarray)) and not any(
            isinstance(s, dict) for s in samples):  # (an iterator is read lazily, as it runs)
        validate.int_words("samples", [list(s) for s in samples], 16, shape=(-1, 7))
    if max_cycles is not None:
        max_cycles = validate.positive_int("max_cycles", max_cycles)

    top = config.top()
    dev = _device(samples, timing)
    faults = dict(faults or {})
    rx = _UartRx(config.baud_div)
    period = config.period
    limit = max_cycles or (n_samples + 1) * period + 100
    cs_rises: list[int] = []
    flags = [(-1, 0)]  # (cycle, uio_out) at every change
    state = {"cycles": 0}

    async def clock(ctx):
        while True:
            ctx.set(top.clk, 1)
            await ctx.delay(CLK_NS * 0.5e-9)
            ctx.set(top.clk, 0)
            await ctx.delay(CLK_NS * 0.5e-9)

    async def bench(ctx):
        ctx.set(top.rst_n, 0)
        for _ in range(2):
            await ctx.posedge(top.clk)
        ctx.set(top.rst_n, 1)
        cycle = 0
        prev_cs = 1
        while len(rx.bytes) < PACKET_LEN * n_samples and cycle < limit:
            _, uo, uio = await ctx.posedge(top.clk).sample(top.uo_out, top.uio_out)
            if uio != flags[-1][1]:
                flags.append((cycle, uio))
            mosi, sclk, cs_n, tx = uo & 1, (uo >> 1) & 1, (uo >> 2) & 1, (uo >> 3) & 1
            if prev_cs and not cs_n:
                k, r = divmod(dev.stats.transactions, 2)
                if r == 0 and k in faults:
                    dev.set_fault(faults[k])
            if cs_n and not prev_cs:
                cs_rises.append(cycle)
            prev_cs = cs_n
            ctx.set(top.ui_in, dev.pins(cycle * CLK_NS, cs_n, sclk, mosi))
            rx.sample(cycle, tx)
            cycle += 1
        state["cycles"] = cycle

    sim = Simulator(top)
    sim.add_process(clock)
    sim.add_testbench(bench)
    t0 = time.perf_counter()
    sim.run()
    seconds = time.perf_counter() - t0
    starts = rx.starts[::PACKET_LEN]
    at_start = [next(v for c, v in reversed(flags) if c < s) for s in starts]
    return RtlRun(bytes(rx.bytes), state["cycles"], seconds,
                  _latencies(cs_rises, rx.starts), dev, rx.errors,
                  {"uio_out_at_packet_start": at_start, "cs_rises": cs_rises})


def _latencies(cs_rises, starts) -> list[int]:
    bursts = cs_rises[1::2]
    firsts = starts[::PACKET_LEN]
    return [s - c for c, s in zip(bursts, firsts, strict=False)]


# ----------------------------------------------------------------------------- Verilator

TB_TOP = "tb_tinykalman"
#: the benches' 10 MHz clock, generated inside the wrapper (Verilator ``--timing``): a clock
#: driven from cocotb costs two Python/VPI round trips per cycle and dominated the run time
_CLOCK = f"""  reg clk = 1'b0;
  always #{CLK_NS // 2} clk = ~clk;"""
_VERILATOR_ARGS = ("--timing", "--timescale", "1ns/1ps", "-CFLAGS", "-std=gnu++20 -fcoroutines")


def tb_wrapper_verilog(dut: str = TT_MODULE_NAME) -> str:
    """A TinyTapeout-style ``tb`` wrapper: instantiates the user module, generates its 10 MHz
    clock, and breaks the seed's pins out as single-bit nets (``miso``, ``mosi``, ``sclk``,
    ``cs_n``, ``tx``, and ``spi`` = the three SPI outputs) so that cocotb (and
    ``cocotbext-uart``) can watch them."""
    return f"""
module {TB_TOP}(input rst_n, input miso, output mosi, output sclk, output cs_n,
                output tx, output [2:0] spi, output [7:0] uo_out, output [7:0] uio_out,
                output [7:0] uio_oe);
  wire [7:0] ui_in = {{7'b0, miso}};
{_CLOCK}
  {dut} dut(.ui_in(ui_in), .uo_out(uo_out), .uio_in(8'b0), .uio_out(uio_out),
            .uio_oe(uio_oe), .ena(1'b1), .clk(clk), .rst_n(rst_n));
  assign mosi = uo_out[0];
  assign sclk = uo_out[1];
  assign cs_n = uo_out[2];
  assign tx = uo_out[3];
  assign spi = uo_out[2:0];  // cs_n, sclk, mosi: one net to watch
endmodule
"""


def build_verilator(config: SimConfig = FAST) -> Path:
    """Compile (or reuse from the harness's cache) the Verilator model of ``config``'s chip
    inside the bench wrapper (:func:`tb_wrapper_verilog`)."""
    from navgate.cache import cached_verilog
    from navgate.gateware.verify import _build_model, emit_verilog

    # the chip's Verilog from navgate's cache when this configuration was emitted before at
    # this version of the sources (the chip is then not even built)
    chip, _ = cached_verilog("TinyKalmanTop", {"top": TT_MODULE_NAME, **config.params()},
                             lambda: emit_verilog(config.top(), TT_MODULE_NAME))
    text = chip + tb_wrapper_verilog()
    return _build_model(text, TB_TOP, _VERILATOR_ARGS)


def run_verilator(samples, n_samples: int, config: SimConfig = FAST, *,
                  timing: SpiTiming | None = None, faults: dict | None = None,
                  work_dir: Path | str | None = None) -> RtlRun:
    """Run ``n_samples`` sample periods of the emitted Verilog in Verilator (cocotb test
    :mod:`navgate.systems.tinykalman.tb_cocotb`). ``samples`` is a sequence of seven-word
    bursts. Returns the UART bytes that ``cocotbext-uart`` received, latencies, and the
    device log (as seen by the cocotb-side device model) in ``extra``."""
    from cocotb_tools.runner import get_runner

    from navgate.gateware.verify import VerifyError, _verilator_path

    n_samples = validate.positive_int("n_samples", n_samples)
    build_dir = build_verilator(config)
    cleanup = work_dir is None
    work = Path(work_dir) if work_dir is not None else Path(tempfile.mkdtemp(prefix="tk-vl-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        words = validate.int_words("samples", [list(s) for s in samples], 16,
                                   shape=(-1, 7))
        np.savetxt(work / "samples.txt", words, fmt="%d")
        job = {
            "samples": str(work / "samples.txt"), "n_samples": int(n_samples),
            "spi_div": config.spi_div, "baud_div": config.baud_div, "period": config.period,
            "clk_ns": CLK_NS, "faults": {str(k): v for k, v in (faults or {}).items()},
            "timing": None if timing is None else timing.__dict__,
            "out": str(work / "result.json"), "uart": str(work / "uart.bin"),
        }
        (work / "job.json").write_text(json.dumps(job))
        log = work / "sim.log"
        t0 = time.perf_counter()
        with _verilator_path():
            runner = get_runner("verilator")
            try:
                runner.test(test_module="navgate.systems.tinykalman.tb_cocotb",
                            hdl_toplevel=TB_TOP, hdl_toplevel_lang="verilog",
                            build_dir=build_dir, test_dir=work,
                            extra_env={"NAVGATE_TK_JOB": str(work / "job.json")},
                            results_xml=str(work / "results.xml"), log_file=log)
            except (SystemExit, subprocess.CalledProcessError) as exc:
                text = log.read_text()[-3000:] if log.exists() else ""
                raise VerifyError(f"cocotb/Verilator run of the TinyKalman top failed ({exc}):"
                                  f"\n{text}") from None
        seconds = time.perf_counter() - t0
        res_path = work / "result.json"
        if not res_path.exists():
            text = log.read_text()[-3000:] if log.exists() else ""
            raise VerifyError(f"the cocotb run wrote no result:\n{text}")
        res = json.loads(res_path.read_text())
        if res.get("error"):
            raise VerifyError(f"cocotb run: {res['error']}")
        uart = (work / "uart.bin").read_bytes()
        dev_log = [(a, bool(r), bytes.fromhex(b)) for a, r, b in res["log"]]
        return RtlRun(uart, res["cycles"], seconds, res["latencies"], None, 0,
                      {"log": dev_log, "violations": res["violations"],
                       "violation_count": res["violation_count"], "stats": res["stats"],
                       "sim_seconds": res.get("seconds")})
    finally:
        if cleanup:
            shutil.rmtree(work, ignore_errors=True)


# ----------------------------------------------------------------------------- stream blocks


def datapath_model(seen: dict) -> dict:
    """Bit-true model of :class:`~navgate.systems.tinykalman.datapath.TinyKalmanDatapath` for
    :func:`navgate.gateware.verify.verify` (walks the samples in order, as the stateful filter
    does; ``ok = 0`` holds the state)."""
    from navgate.systems.tinykalman.model import accel_angles, run_sequence

    ok = np.asarray(seen["ok"], dtype=np.int64)
    roll, pitch, rm, pm = run_sequence(seen["ax"], seen["ay"], seen["az"], seen["gx"],
                                       seen["gy"], valid=ok)
    _, _, _, sat = accel_angles(seen["ax"], seen["ay"], seen["az"])
    return {"roll": roll, "pitch": pitch, "roll_m": rm, "pitch_m": pm,
            "sat": (sat & ok.astype(bool)).astype(np.int64), "ok": ok}


def datapath_inputs(words, ok=None) -> dict:
    """Input arrays of the data path block from :class:`~.run.Words`."""
    n = len(words)
    d = {k: words.column(k) for k in ("ax", "ay", "az", "gx", "gy")}
    if ok is None:
        d["ok"] = np.ones(n, np.int64)
    else:
        ok = np.asarray(ok)
        d["ok"] = (ok.astype(np.int64) if ok.dtype == np.bool_
                   else validate.int_words("ok", ok, 1, signed=False))
        if d["ok"].shape != (n,):
            raise ValueError(f"ok: shape {d['ok'].shape} differs from the words' {(n,)}")
    return d


def directed_angles() -> dict:
    """Accelerometer words at every sign combination (the four quadrants of (az, ay), both signs
    of ax) and the 16-bit extremes: -32768, -32767, -16384, -1, 0, 1, 16384, 32766, 32767 on ay
    and az (the (32767, 32767) corner saturates mag_yz; (0, 0) is included), five values of ax."""
    e = (-32768, -32767, -16384, -1, 0, 1, 16384, 32766, 32767)
    g = np.array(np.meshgrid(e, e, (-32768, -1, 0, 1, 32767))).reshape(3, -1)
    return {"ay": g[0].astype(np.int64), "az": g[1].astype(np.int64),
            "ax": g[2].astype(np.int64)}
