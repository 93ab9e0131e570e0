"""The ``rtl`` engine: seed 000's PL engines as gateware (``ins_engines``, the scheduled
float32 datapath of :mod:`navgate.systems.ins_trn.pl.nav_engines`) running in Verilator, driven call
by call through a persistent native model (:mod:`navgate.gateware.native_stream`; the
verification harness's VPI model of the same Verilog is checked in
tests/systems/ins_trn/pl/test_engines.py).

The PS side is the ``fp32`` engine's (:class:`navgate.systems.ins_trn.ps.fp32_engine.Fp32Engine`):
its register writes (configuration, initial state) are computed as there and loaded into the
gateware's register file; every engine call then runs in the gateware (propagate: per IMU
sample, six word writes and one run; updates: input writes, the gate half, and the apply half
when the gate's flags say so), and after each call the state registers are read back from
the gateware into the PS's copy, from which the read calls answer. The result must equal the
``fp32`` engine's bit for bit (tests/systems/ins_trn/ps/test_rtl_engine.py).
"""

from __future__ import annotations

import dataclasses
import time
import weakref

import numpy as np

from navgate.numerics.fp32 import bits_to_float, float_to_bits
from navgate.opflow.machine import CMD_READ, CMD_START, CMD_WRITE, ScheduledMachineStream
from navgate.systems.ins_trn.pl.fp32_exec import to_f32
from navgate.systems.ins_trn.pl.fp32_program import CONFIG_REGS, STATE_REGS
from navgate.systems.ins_trn.pl.nav_engines import ENGINE_UNITS, IMU_WORDS
from navgate.systems.ins_trn.pl.register_engine import pl_engine_image
from navgate.systems.ins_trn.ps.fp32_engine import Fp32Engine
from navgate.systems.ins_trn.ps.pl_interface import EngineSetup, check_imu_words

__all__ = ["RtlEngine", "NativeLink", "RtlError"]


class RtlError(RuntimeError):
    """The Verilator co-simulation failed or answered unexpectedly."""


class NativeLink:
    """A running native Verilator model of a :class:`ScheduledMachineStream`
    (:class:`navgate.gateware.native_stream.NativeStreamServer`: no VPI, optimised model);
    ``batch`` runs command rows and returns the response fields. The response of every
    command is taken when the wrapper offers it; ``waits`` are checked through the run
    commands' ``cycles``."""

    def __init__(self, image, design: str | None = None, params: dict | None = None):
        from navgate.gateware.native_stream import NativeStreamServer

        # ``design``/``params``: what built ``image`` (the Verilog is then cached by them)
        self.server = NativeStreamServer(ScheduledMachineStream(image), design=design,
                                         params=params)
        self.cycles_run = 0
        #: wall seconds spent in the model's batches (the simulation itself)
        self.batch_seconds = 0.0

    def batch(self, rows, waits) -> dict:
        from navgate.gateware.native_stream import NativeStreamError

        arr = np.array(rows, dtype=np.int64).reshape(-1, 4)
        t0 = time.perf_counter()
        try:
            return self.server.batch({"cmd": arr[:, 0], "addr": arr[:, 1], "data": arr[:, 2],
                                      "prog": arr[:, 3]})
        except NativeStreamError as exc:
            raise RtlError(str(exc)) from None
        finally:
            self.batch_seconds += time.perf_counter() - t0

    def close(self):
        self.server.close()


class _RtlMachine:
    """The PS's view of the gateware register file, shaped like ``fp32_exec.Machine``
    (``run``, ``regs``, ``index``, ``get``): calls run in the gateware."""

    def __init__(self, machine, image, link: NativeLink):
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
            self._m.regs[self._m.index[n]] = bits_to_float(int(data[start + k]))
        return [int(v) for v in data[start + len(back):]]

    def set(self, name, value):
        """A PS register write (e.g. the monitor's covariance inflation): into the PS's copy
        and the gateware's register file."""
        self._m.set(name, value)
        bits = float_to_bits(self._m.regs[self._m.index[name]])
        self.link.batch([(CMD_WRITE, self.addr[name], bits, 0)], [1])

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
        return {n: bits_to_float(w) for n, w in zip(outs, words, strict=True)}


class RtlEngine(Fp32Engine):
    """The gateware of seed 000's PL engines in Verilator behind the PlEngine interface."""

    name = "rtl"
    #: the PL engine in Verilator (register_engine.PL_ENGINES)
    pl_engine = "banked"

    def __init__(self, setup: EngineSetup, *, check_pd: bool = False):
        super().__init__(setup, check_pd=check_pd)
        image = pl_engine_image(self.pl_engine)
        # the image is engine_image's defaults (its programs and ENGINE_UNITS) or the
        # register machine's, all in the source that the Verilog cache's key covers
        params = ({"engine_image": "ins_engines", "units": dataclasses.asdict(ENGINE_UNITS)}
                  if self.pl_engine == "banked" else {"engine_image": self.pl_engine})
        self.link = NativeLink(image, design="ScheduledMachineStream", params=params)
        self._finalizer = weakref.finalize(self, self.link.close)
        self.m = _RtlMachine(self.m, image, self.link)
        self.m.load()

    def propagate(self, gyro_words, accel_words) -> None:
        gw, aw = check_imu_words(gyro_words, accel_words)
        gw, aw = gw.astype(np.int64), aw.astype(np.int64)
        self.m.propagate(gw, aw)
        self.samples += gw.shape[0]

    def hardware_stats(self) -> dict:
        return {"engine_cycles": self.link.cycles_run,
                "engine_cycles_per_imu_sample": self.link.cycles_run / max(self.samples, 1)}

    def close(self):
        self._finalizer()


class RtlCompactEngine(RtlEngine):
    """``rtl`` with the register machine (docs/opflow-register-machine.md) in Verilator,
    behind the same ports and addresses."""

    name = "rtl-compact"
    pl_engine = "register"
