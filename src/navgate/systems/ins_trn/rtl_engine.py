"""The ``rtl`` engine: seed 000's PL engines as gateware (``ins_engines``, the scheduled
float32 datapath of :mod:`navgate.systems.ins_trn.engines`) running in Verilator, driven call
by call through a persistent native model (:mod:`navgate.gateware.native_stream`, the
default) or the verification harness's cocotb model and server
(:mod:`navgate.systems.ins_trn.rtl_server`, ``backend="cocotb"``).

The PS side is the ``fp32`` engine's (:class:`navgate.systems.ins_trn.fp32_engine.Fp32Engine`):
its register writes (configuration, initial state) are computed as there and loaded into the
gateware's register file; every engine call then runs in the gateware (propagate: per IMU
sample, six word writes and one run; updates: input writes, the gate half, and the apply half
when the gate's flags say so), and after each call the state registers are read back from
the gateware into the PS's copy, from which the read calls answer. The result must equal the
``fp32`` engine's bit for bit (tests/systems/ins_trn/test_rtl_engine.py).
"""

from __future__ import annotations

import os
import shutil
import tempfile
import threading
import time
import weakref
from pathlib import Path

import numpy as np

from navgate.gateware import verify as V
from navgate.gateware.scheduled import CMD_READ, CMD_START, CMD_WRITE, ScheduledMachineStream
from navgate.systems.ins_trn.engine import EngineSetup
from navgate.systems.ins_trn.engines import IMU_WORDS, engine_image
from navgate.systems.ins_trn.fp32_engine import Fp32Engine
from navgate.systems.ins_trn.fp32_exec import float_to_bits, to_f32
from navgate.systems.ins_trn.fp32_program import CONFIG_REGS, STATE_REGS

__all__ = ["RtlEngine", "RtlLink", "NativeLink", "RtlError"]


class RtlError(RuntimeError):
    """The Verilator co-simulation failed or answered unexpectedly."""


def _f(bits: int) -> float:
    return float(np.uint32(bits).view(np.float32))


class NativeLink:
    """A running native Verilator model of a :class:`ScheduledMachineStream`
    (:class:`navgate.gateware.native_stream.NativeStreamServer`: no VPI, optimised model);
    the same ``batch``/``close`` as :class:`RtlLink`. The response of every command is taken
    when the wrapper offers it; ``waits`` are checked through the run commands' ``cycles``."""

    def __init__(self, image):
        from navgate.gateware.native_stream import NativeStreamServer

        self.server = NativeStreamServer(ScheduledMachineStream(image))
        self.cycles_run = 0

    def batch(self, rows, waits) -> dict:
        from navgate.gateware.native_stream import NativeStreamError

        arr = np.array(rows, dtype=np.int64).reshape(-1, 4)
        try:
            return self.server.batch({"cmd": arr[:, 0], "addr": arr[:, 1], "data": arr[:, 2],
                                      "prog": arr[:, 3]})
        except NativeStreamError as exc:
            raise RtlError(str(exc)) from None

    def close(self):
        self.server.close()


class RtlLink:
    """A running Verilator model of a :class:`ScheduledMachineStream` with a command pipe
    (cocotb server, :mod:`navgate.systems.ins_trn.rtl_server`)."""

    def __init__(self, image, start_timeout: float = 600.0):
        comp = ScheduledMachineStream(image)
        self.in_fmt = V.stream_format(V._port_shape(comp.i))
        self.out_fmt = V.stream_format(V._port_shape(comp.o))
        build_dir = V._build_model(V.emit_verilog(comp, "dut"), "dut")
        self.work = Path(tempfile.mkdtemp(prefix="navgate-rtl-"))
        cmd, rsp = self.work / "cmd", self.work / "rsp"
        os.mkfifo(cmd)
        os.mkfifo(rsp)
        self.error: list = []

        def run():
            from cocotb_tools.runner import get_runner

            try:
                with V._verilator_path():
                    get_runner("verilator").test(
                        test_module="navgate.systems.ins_trn.rtl_server", hdl_toplevel="dut",
                        hdl_toplevel_lang="verilog", build_dir=build_dir, test_dir=self.work,
                        extra_env={"NAVGATE_RTL_CMD": str(cmd), "NAVGATE_RTL_RSP": str(rsp)},
                        results_xml=str(self.work / "results.xml"),
                        log_file=self.work / "sim.log")
            except BaseException as exc:  # noqa: BLE001 - reported to the caller
                self.error.append(repr(exc))

        self.thread = threading.Thread(target=run, daemon=True)
        self.thread.start()
        deadline = time.monotonic() + start_timeout
        fd = None
        while fd is None:
            try:
                fd = os.open(cmd, os.O_WRONLY | os.O_NONBLOCK)
            except OSError:
                if not self.thread.is_alive() or time.monotonic() > deadline:
                    raise RtlError(f"Verilator server did not start: {self.error}") from None
                time.sleep(0.05)
        os.set_blocking(fd, True)
        self.cmd = os.fdopen(fd, "w")
        self.rsp = open(rsp)
        self.cycles_run = 0

    def batch(self, rows, waits) -> dict:
        """Run command rows ``(cmd, addr, data, prog)``, the response of each expected
        ``waits`` cycles after it is accepted; returns the response fields."""
        arr = np.array(rows, dtype=np.int64).reshape(-1, 4)
        packed = V.pack(self.in_fmt, {"cmd": arr[:, 0], "addr": arr[:, 1],
                                      "data": arr[:, 2], "prog": arr[:, 3]})
        self.cmd.write(" ".join(f"{v:x}/{w}" for v, w in zip(packed, waits, strict=True))
                       + "\n")
        self.cmd.flush()
        line = self.rsp.readline()
        if line.startswith("!"):
            raise RtlError(f"Verilator server: {line[1:].strip()}")
        outs = [int(t, 16) for t in line.split()]
        if len(outs) != len(packed):
            raise RtlError(f"server answered {len(outs)} of {len(packed)} commands "
                           f"({self.error})")
        return V.unpack(self.out_fmt, outs)

    def close(self):
        try:
            self.cmd.write("quit\n")
            self.cmd.close()
            self.rsp.close()
        except OSError:
            pass
        self.thread.join(timeout=30)
        shutil.rmtree(self.work, ignore_errors=True)


class _RtlMachine:
    """The PS's view of the gateware register file, shaped like ``fp32_exec.Machine``
    (``run``, ``regs``, ``index``, ``get``): calls run in the gateware."""

    def __init__(self, machine, image, link: RtlLink):
        self._m = machine
        self.image = image
        self.link = link
        self.keys = list(image.programs)
        self.addr = image.layout.fixed
        self.readback = [n for n in STATE_REGS if n not in CONFIG_REGS]

    def __getattr__(self, name):
        return getattr(self._m, name)

    def load(self):
        rows = []
        for n, a in self.addr.items():
            if n.startswith("c:"):
                continue
            bits = float_to_bits(self._m.regs[self._m.index[n]]) if n in self._m.index else 0
            rows.append((CMD_WRITE, a, bits, 0))
        self.link.batch(rows, self._waits(rows))

    def _waits(self, rows):
        """Cycles from acceptance to response (ScheduledMachineStream's timing)."""
        return [1 if r[0] == CMD_WRITE else 2 if r[0] == CMD_READ
                else self.image.cycles(self.keys[r[3]]) + 2 for r in rows]

    def _run_rows(self, key):
        return (CMD_START, 0, 0, self.keys.index(key))

    def _finish(self, rows, runs, extra_reads=()):
        rows = list(rows)
        start = len(rows)
        # read back the registers the programs run here commit (the PS's copy of the rest
        # is unchanged)
        changed = set()
        for _, key in runs:
            changed.update(self.image.programs[key].commit)
        back = [n for n in self.readback if n in changed]
        rows += [(CMD_READ, self.addr[n], 0, 0) for n in back]
        rows += [(CMD_READ, a, 0, 0) for a in extra_reads]
        out = self.link.batch(rows, self._waits(rows))
        cyc = out["cycles"]
        for row, key in runs:
            if int(cyc[row]) != self.image.cycles(key) + 1:
                raise RtlError(f"{key} took {int(cyc[row])} cycles, schedule says "
                               f"{self.image.cycles(key) + 1}")
            self.link.cycles_run += int(cyc[row])
        data = out["data"]
        for k, n in enumerate(back):
            self._m.regs[self._m.index[n]] = _f(int(data[start + k]))
        return [int(v) for v in data[start + len(back):]]

    def propagate(self, gyro_words, accel_words):
        rows, runs = [], []
        for g, a in zip(gyro_words, accel_words, strict=True):
            for name, w in zip(IMU_WORDS, list(g) + list(a), strict=True):
                rows.append((CMD_WRITE, self.addr[name], int(w) & 0xFFFFFFFF, 0))
            runs.append((len(rows), "propagate"))
            rows.append(self._run_rows("propagate"))
        self._finish(rows, runs)

    def run(self, key, **inputs) -> dict:
        rows = []
        for name, v in inputs.items():
            value = to_f32(v)
            self._m.regs[self._m.index[name]] = value
            rows.append((CMD_WRITE, self.addr[name], float_to_bits(value), 0))
        runs = [(len(rows), key)]
        rows.append(self._run_rows(key))
        outs = self.image.output_addr(key)
        words = self._finish(rows, runs, list(outs.values()))
        return {n: _f(w) for n, w in zip(outs, words, strict=True)}


class RtlEngine(Fp32Engine):
    """The gateware of seed 000's PL engines in Verilator behind the PlEngine interface."""

    name = "rtl"

    def __init__(self, setup: EngineSetup, *, check_pd: bool = False,
                 backend: str = "native"):
        super().__init__(setup, check_pd=check_pd)
        image = engine_image("ins_engines")
        if backend not in ("native", "cocotb"):
            raise ValueError(f"unknown RTL backend {backend!r} (native or cocotb)")
        self.link = NativeLink(image) if backend == "native" else RtlLink(image)
        self._finalizer = weakref.finalize(self, self.link.close)
        self.m = _RtlMachine(self.m, image, self.link)
        self.m.load()

    def propagate(self, gyro_words, accel_words) -> None:
        gw = np.asarray(gyro_words, dtype=np.int64).reshape(-1, 3)
        aw = np.asarray(accel_words, dtype=np.int64).reshape(-1, 3)
        self.m.propagate(gw, aw)
        self.samples += gw.shape[0]

    def close(self):
        self._finalizer()
