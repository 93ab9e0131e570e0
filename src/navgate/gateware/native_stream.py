"""A persistent native Verilator process serving command batches to a stream component.

The cocotb harness (:mod:`navgate.gateware.verify`) builds Verilator models with VPI and every
signal public, which keeps Verilator from optimising the model; for seed 000's engines it
simulates about 13,000 cycles/s. This module compiles the emitted Verilog with a small C++
main (no VPI, no cocotb) that reads batches of input payloads on stdin, one line per batch
(space-separated hex words, packed as :func:`navgate.gateware.verify.pack` does), drives them
through the component's ``i`` stream under the harness's stream rules (offer the next payload
while ``i.valid``, take every output with ``o.ready = 1``) and answers one line per batch: the
output payloads (hex), one per input, space-separated, or ``!reason``. ``quit`` ends it.

Verilator names a port ``i__valid`` ``i___05Fvalid`` in C++. Compiled models are cached under
:func:`navgate.gateware.verify.verilator_cache_dir` (keyed by the Verilog and the driver).
"""

from __future__ import annotations

import fcntl
import hashlib
import shutil
import subprocess
import tempfile
import time
from importlib import resources
from pathlib import Path

from navgate.gateware import verify as V

__all__ = ["NativeStreamServer", "NativeStreamError", "compile_native", "build_native",
           "simulate_native_stream"]


class NativeStreamError(RuntimeError):
    """The native model failed to build, or answered unexpectedly."""


#: the C++ server, a template shipped as package data (``native/stream_server.cpp``)
def _server_template() -> str:
    """The C++ server's source template, package data ``gateware/native/stream_server.cpp`` (a
    leading newline keeps the generated source, the key of its compiled-model cache, as it
    was when the template lived in this module)."""
    return "\n" + (resources.files("navgate.gateware") / "native" / "stream_server.cpp").read_text()


def _payload_code(width: int, port: str, write: bool) -> str:
    words = (width + 31) // 32
    if width <= 32:
        return (f"            top->{port} = in[0];" if write else
                f'                snprintf(hexbuf, sizeof hexbuf, "%x", '
                f"(uint32_t)top->{port});")
    if width <= 64:
        return (f"            top->{port} = ((uint64_t)in[1] << 32) | in[0];" if write else
                f'                snprintf(hexbuf, sizeof hexbuf, "%lx", '
                f"(unsigned long)top->{port});")
    if write:
        return "\n".join(f"            top->{port}[{i}] = in[{i}];" for i in range(words))
    if words > 7:
        raise NativeStreamError("output payload wider than 224 bits")
    fmt = "%x" + "%08x" * (words - 1)
    args = ", ".join(f"(uint32_t)top->{port}[{i}]" for i in reversed(range(words)))
    return f'                snprintf(hexbuf, sizeof hexbuf, "{fmt}", {args});'


def native_key(verilog_text: str, main_src: str, top: str) -> str:
    """The cache key of a native model (see :func:`compile_native`)."""
    return hashlib.sha256("\0".join([verilog_text, main_src, top]).encode()).hexdigest()[:24]


def compile_native(verilog_text: str, main_src: str, top: str, kind: str = "server") -> Path:
    """Compile ``verilog_text`` with the C++ ``main_src`` by Verilator (no VPI, ``-O1``), or
    find it in the cache (keyed by both texts); the executable ``V<top>``."""
    key = native_key(verilog_text, main_src, top)
    root = V.verilator_cache_dir()
    root.mkdir(parents=True, exist_ok=True)
    out = root / f"{kind}-{top}-{key}"
    exe = out / f"V{top}"
    if exe.exists():
        return exe
    with open(root / f"{kind}-{top}-{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if exe.exists():
            return exe
        tmp = Path(tempfile.mkdtemp(prefix=f"{kind}-{top}-", dir=root))
        (tmp / f"{top}.v").write_text(verilog_text)
        (tmp / "main.cpp").write_text(main_src)
        cmd = ["verilator", "--cc", "--exe", "--build", "-j", "2", "-Wno-fatal", "-Wno-lint",
               "-Wno-style", "--top-module", top, "-Mdir", str(tmp / "obj"), f"{top}.v",
               "main.cpp", "-o", f"V{top}"]
        env = V._env_with_verilator()
        env["MAKEFLAGS"] = "OPT_FAST=-O1 OPT_SLOW=-O0 OPT_GLOBAL=-O1 CFG_CXXFLAGS_PCH_I=-include"
        from navgate.gateware.objcache import wrapper

        objcache = wrapper(root)  # Verilator's runtime objects compiled once for all models
        if objcache:
            env["MAKEFLAGS"] += f" OBJCACHE={objcache}"
        with V.build_clock(top, key, kind, verilog_text) as record:
            r = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True)
        if r.returncode != 0:
            raise NativeStreamError(f"native Verilator build of {top} failed:\n"
                                    f"{(r.stdout + r.stderr)[-4000:]}")
        out.mkdir(parents=True, exist_ok=True)
        V.record_build(out, record)
        shutil.copy2(tmp / "obj" / f"V{top}", exe)
        shutil.rmtree(tmp, ignore_errors=True)
    return exe


def build_native(verilog_text: str, top: str, in_width: int, out_width: int) -> Path:
    """Compile (or find in the cache) the native server of ``top``; the executable."""
    src = _server_template() % {"top": top, "in_words": (in_width + 31) // 32,
                   "set_payload": _payload_code(in_width, "i___05Fpayload", True),
                   "get_payload": _payload_code(out_width, "o___05Fpayload", False)}
    return compile_native(verilog_text, src, top, "server")


class NativeStreamServer:
    """A running native model of a stream ``component``: :meth:`batch` sends packed input
    payloads and returns the packed outputs (one per input)."""

    def __init__(self, component, top: str = "dut", idle_limit: int = 100_000, *,
                 design: str | None = None, params: dict | None = None):
        self.in_fmt = V.stream_format(V._port_shape(component.i))
        self.out_fmt = V.stream_format(V._port_shape(component.o))
        t0 = time.perf_counter()
        # with ``design``, the Verilog may come from navgate's cache (V.emit_verilog)
        text = V.emit_verilog(component, top, design=design, params=params)
        #: seconds spent getting the Verilog (elaborating, or reading the cache) and building
        #: (or finding) the compiled model
        self.verilog_seconds = time.perf_counter() - t0
        self.exe = build_native(text, top, self.in_fmt.width, self.out_fmt.width)
        self.build_seconds = time.perf_counter() - t0
        self.model_seconds = self.build_seconds - self.verilog_seconds
        self.proc = subprocess.Popen([str(self.exe), str(idle_limit)], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, bufsize=1)

    def batch(self, fields: dict) -> dict:
        """Per-field input arrays in, per-field output arrays out (as ``verify.simulate``)."""
        return V.unpack(self.out_fmt, self.batch_packed(V.pack(self.in_fmt, fields)))

    def batch_packed(self, packed: list[int]) -> list[int]:
        """Packed input payloads in (:func:`navgate.gateware.verify.pack`), packed outputs out
        (one per input)."""
        if not len(packed):
            return []
        try:
            self.proc.stdin.write(" ".join(format(v, "x") for v in packed) + "\n")
            self.proc.stdin.flush()
            line = self.proc.stdout.readline()
        except (BrokenPipeError, OSError) as exc:
            raise NativeStreamError(f"native model exited: {exc}") from None
        if not line:
            err = self.proc.stderr.read() if self.proc.poll() is not None else ""
            raise NativeStreamError(f"native model exited: {err[-2000:]}")
        if line.startswith("!"):
            raise NativeStreamError(f"native model: {line[1:].strip()}")
        outs = [int(t, 16) for t in line.split()]
        if len(outs) != len(packed):
            raise NativeStreamError(f"native model answered {len(outs)} of {len(packed)}")
        return outs

    def close(self):
        if self.proc.poll() is None:
            try:
                self.proc.stdin.write("quit\n")
                self.proc.stdin.close()
                self.proc.wait(timeout=30)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
        for f in (self.proc.stdout, self.proc.stderr):
            try:
                f.close()
            except OSError:
                pass


def simulate_native_stream(component, packed: list[int], *, top: str = "dut",
                           idle_limit: int = 100_000, design: str | None = None,
                           params: dict | None = None, valid_prob: float = 1.0,
                           ready_prob: float = 1.0, seed: int = 0) -> V.SimRun:
    """Stream ``packed`` through ``component`` compiled by Verilator without VPI
    (:class:`navgate.gateware.native_stream.NativeStreamServer`, the model ``navgate fly
    --engine rtl`` runs): every input offered as soon as the last one is taken, every output
    taken when offered, so the same model serves the CLI and the tests (one build). Pass it
    as ``backend`` to :func:`navgate.gateware.verify.verify`. It does
    not count cycles or draw random gaps: ``valid_prob``/``ready_prob`` other than 1 are
    refused (use ``"verilator"`` or ``"amaranth"`` for those)."""
    if valid_prob != 1.0 or ready_prob != 1.0:
        raise ValueError("the native back end offers every input and takes every output at "
                         "once; use backend='verilator' for random valid/ready gaps")
    del seed  # nothing random to seed
    server = NativeStreamServer(component, top, idle_limit, design=design,
                                params=dict(params) if params is not None else None)
    try:
        t0 = time.perf_counter()
        outs = server.batch_packed(packed)
        seconds = time.perf_counter() - t0
    finally:
        server.close()
    return V.SimRun(outs, None, None, seconds)
