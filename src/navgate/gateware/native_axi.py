"""A persistent native Verilator co-simulation of a component with an AXI4-Lite slave port.

The processor-side software of a system (Python) drives the fabric through its AXI4-Lite
register bank (:mod:`navgate.gateware.axi_lite`) and feeds it input streams; it must stay out
of the per-cycle path. As :mod:`navgate.gateware.native_stream` does for stream components,
this module compiles the emitted Verilog with a small C++ main (no VPI, no cocotb) into a
process that runs cycle by cycle at Verilator speed and takes *batches of bus commands* on
stdin, one batch per line, answering one line per batch.

The component must have

* ``clk``, ``rst``: the ``sync`` domain (reset is held for 2 cycles at start; cycles are
  counted from the end of reset);
* ``axi``: ``In(axi_lite_signature(addr_width))`` (the component is the slave, 32-bit data);
* any number of input streams ``In(stream.Signature(layout))`` (named to the server; payloads
  of any width, packed as :func:`navgate.gateware.verify.pack` does);
* any number of 1-bit outputs to watch (e.g. ``irq``).

Other input ports are held at 0.

Protocol (tokens separated by spaces; addresses, data, masks and payloads in hex, counts,
indices and limits in decimal; one answer token per command, in order)::

    W <addr> <data> <strb>         AXI4-Lite write           -> bresp digit (0 OKAY, 2 SLVERR)
    R <addr>                       AXI4-Lite read            -> rdata hex, "/<rresp>" if not OKAY
    S <k> <payload>                push into input stream k  -> "."  (waits for ready)
    C <n>                          run n idle clock cycles   -> "."
    P <addr> <mask> <value> <lim>  read until (rdata & mask) == value, at most lim cycles
                                                             -> the final rdata hex
    Q <k> <lim>                    run until watched output k is high, at most lim cycles
                                                             -> cycles waited (0 if high now)
    T                              cycles since reset        -> decimal

A batch that cannot be carried out answers ``!reason`` for the whole line (the commands
before the failing one have taken effect; the rest are skipped). A malformed batch is
rejected before any command runs. A poll or wait that runs out of cycles leaves the model
usable (the bus is idle between reads); a bus transaction or stream push that gets no
handshake within the per-transaction limit cannot be abandoned without breaking the
protocol, so the model is then *wedged* and answers every later batch with ``!``.
``quit`` ends the process, which prints ``cycles <total>`` on stderr.

The C++ master obeys AXI4-Lite (ARM IHI 0022, A3.2-A3.3): a valid never waits for a ready,
the payload (address, data, strobe) is set before valid rises and holds until the handshake,
AW and W are offered together (or W ``skew`` cycles after AW, AW ``-skew`` after W) and B and R
are taken with ready high. One transaction runs at a time, in command order. With
``delay_probability > 0`` every channel (AW, W, AR valid; B, R ready; each stream's valid)
waits a seeded random number of cycles (1..``max_delay`` with that probability, else 0), so
the slave's handling of every channel order and of backpressure is exercised. With no delays
and :class:`navgate.gateware.axi_lite.AxiLiteRegisterBank` a write costs exactly 3 cycles and
a read 2; a stream push costs 1 cycle plus the cycles the stream's ready is low.

Verilator names a port ``axi__awaddr`` ``axi___05Fawaddr`` in C++. Compiled models are cached
by :func:`navgate.gateware.native_stream.compile_native` (the delays are run-time options:
one build serves every mode).
"""

from __future__ import annotations

import contextlib
import subprocess
import time
from collections.abc import Iterable, Mapping, Sequence
from importlib import resources

import numpy as np
from amaranth.lib import wiring

from navgate.gateware import verify as V
from navgate.gateware.native_stream import compile_native
from navgate.hw.regmap import OKAY, Reading

__all__ = ["NativeAxiSim", "NativeAxiBus", "NativeAxiWindow", "NativeAxiError",
           "AxiResponseError", "build_native_axi"]


class NativeAxiError(RuntimeError):
    """The native model failed to build, rejected a batch, or timed out."""


class AxiResponseError(OSError):
    """A transaction answered SLVERR/DECERR where OKAY was required."""


_RESP_NAMES = {0: "OKAY", 1: "EXOKAY", 2: "SLVERR", 3: "DECERR"}

#: the C++ server, a template shipped as package data (``native/axi_server.cpp``)
def _server_template() -> str:
    """The C++ server's source template, package data ``gateware/native/axi_server.cpp`` (a
    leading newline keeps the generated source, the key of its compiled-model cache, as it
    was when the template lived in this module)."""
    return "\n" + (resources.files("navgate.gateware") / "native" / "axi_server.cpp").read_text()


def _cxx(name: str) -> str:
    """Verilator's C++ name of a port: every ``__`` becomes ``___05F``."""
    out, i = [], 0
    while i < len(name):
        if name.startswith("__", i):
            out.append("___05F")
            i += 2
        else:
            out.append(name[i])
            i += 1
    return "".join(out)


def _set_payload(k: int, port: str, width: int) -> str:
    p = f"top->{_cxx(port)}"
    if width <= 32:
        body = f"{p} = w[0];"
    elif width <= 64:
        body = f"{p} = ((uint64_t)w[1] << 32) | w[0];"
    else:
        body = " ".join(f"{p}[{i}] = w[{i}];" for i in range((width + 31) // 32))
    return f"    case {k}: {body} break;"


def build_native_axi(verilog_text: str, top: str, addr_width: int,
                     streams: Sequence[tuple[str, int]], watch: Sequence[str]):
    """Compile (or find in the cache) the co-simulation server of ``top``: ``streams`` as
    (port prefix, payload width), ``watch`` the 1-bit output names; the executable."""
    widths = [w for _, w in streams]
    src = _server_template()
    subs = {
        "@TOP@": top,
        "@N_STREAMS@": str(len(streams)),
        "@N_WATCH@": str(len(watch)),
        "@MAX_WORDS@": str(max([1] + [(w + 31) // 32 for w in widths])),
        "@STREAM_WIDTHS@": ", ".join(str(w) for w in [*widths, 0]),
        "@ADDR_MASK@": f"0x{(1 << addr_width) - 1:x}",
        "@SET_VALID@": "\n".join(f"    case {k}: top->{_cxx(n + '__valid')} = v; break;"
                                 for k, (n, _) in enumerate(streams)),
        "@GET_READY@": "\n".join(f"    case {k}: return top->{_cxx(n + '__ready')};"
                                 for k, (n, _) in enumerate(streams)),
        "@SET_PAYLOAD@": "\n".join(_set_payload(k, n + "__payload", w)
                                   for k, (n, w) in enumerate(streams)),
        "@GET_WATCH@": "\n".join(f"    case {k}: return top->{_cxx(n)};"
                                 for k, n in enumerate(watch)),
    }
    for key, value in subs.items():
        src = src.replace(key, value)
    return compile_native(verilog_text, src, top, "axi")


def _member(component, name: str):
    members = component.signature.members
    if name not in members:
        raise NativeAxiError(f"{type(component).__name__} has no port {name!r}")
    return members[name]


class NativeAxiSim:
    """A running native co-simulation of ``component`` (see the module docstring).

    ``streams`` names the input streams (index k in the protocol is the k-th name) and
    ``watch`` the 1-bit outputs. ``delay_probability``/``max_delay``/``seed`` switch on random
    per-channel delays, ``skew`` offsets W from AW; ``limit`` bounds each bus transaction and
    stream push (cycles). ``verilog`` is the component's Verilog (top module ``top``) when the
    caller has it already (emitting a large design takes a while). Use as a context manager,
    or call :meth:`close`.
    """

    def __init__(self, component, streams: Sequence[str] = (), watch: Sequence[str] = (), *,
                 addr_width: int | None = None, top: str = "dut", limit: int = 100_000,
                 delay_probability: float = 0.0, max_delay: int = 3, seed: int = 0,
                 skew: int = 0, verilog: str | None = None):
        axi = _member(component, "axi")
        if not axi.is_signature or axi.flow != wiring.In:
            raise NativeAxiError("port 'axi' must be In(axi_lite_signature(...))")
        width = len(component.axi.awaddr)
        if addr_width is not None and addr_width != width:
            raise NativeAxiError(f"addr_width {addr_width} != the component's {width}")
        if len(component.axi.wdata) != 32:
            raise NativeAxiError("only 32-bit AXI4-Lite data is supported")
        self.addr_width = width
        self.streams = tuple(streams)
        self.watch = tuple(watch)
        self.formats = {}
        for name in self.streams:
            m = _member(component, name)
            port = getattr(component, name)
            if not (m.is_signature and m.flow == wiring.In and hasattr(port, "payload")
                    and hasattr(port, "valid") and hasattr(port, "ready")):
                raise NativeAxiError(f"port {name!r} is not an input stream")
            self.formats[name] = V.stream_format(V._port_shape(port))
        for name in self.watch:
            m = _member(component, name)
            if not (m.is_port and m.flow == wiring.Out and len(getattr(component, name)) == 1):
                raise NativeAxiError(f"port {name!r} is not a 1-bit output")
        for name in (*self.streams, *self.watch):
            if not name.isidentifier() or "__" in name:
                raise NativeAxiError(f"port name {name!r} must be an identifier without '__'")
        if not 0.0 <= delay_probability <= 1.0:
            raise NativeAxiError("delay_probability must be in [0, 1]")
        t0 = time.perf_counter()
        if verilog is None:
            verilog = V.emit_verilog(component, top)
        self.exe = build_native_axi(
            verilog, top, width,
            [(n, self.formats[n].width) for n in self.streams], self.watch)
        self.build_seconds = time.perf_counter() - t0
        args = [str(self.exe), "--limit", str(int(limit)), "--seed", str(int(seed)),
                "--delay-p", repr(float(delay_probability)), "--max-delay",
                str(int(max_delay)), "--skew", str(int(skew))]
        self.proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, bufsize=1)
        #: round trips to the process so far, and commands sent
        self.batches = 0
        self.commands = 0
        #: the total printed by the process when it ended (None while it runs)
        self.final_cycles: int | None = None
        self._depth = 0
        self._queue: list[str] = []
        #: per queued command: kind, address, check the response, the Reading to fill in
        self._checks: list[tuple[str, int, bool, Reading | None]] = []

    # ------------------------------------------------------------------ transport
    def batch(self, commands: Iterable[str]) -> list[str]:
        """Send raw protocol commands (strings like ``"W 10 ff"``) as one line, preceded by
        any writes queued by :meth:`deferred`; their answers, one per command."""
        return self._send(list(commands))

    def _send(self, commands: list[str]) -> list[str]:
        queued, checks = self._queue, self._checks
        self._queue, self._checks = [], []
        full = queued + commands
        if not full:
            return []
        line = " ".join(full)
        if "\n" in line or "quit" in line:
            raise NativeAxiError("a command contains a newline or 'quit'")
        try:
            self.proc.stdin.write(line + "\n")
            self.proc.stdin.flush()
            answer = self.proc.stdout.readline()
        except (BrokenPipeError, OSError, ValueError) as exc:
            raise NativeAxiError(f"native model exited: {exc}") from None
        self.batches += 1
        self.commands += len(full)
        if not answer:
            err = self.proc.stderr.read() if self.proc.poll() is not None else ""
            raise NativeAxiError(f"native model exited: {err[-2000:]}")
        if answer.startswith("!"):
            raise NativeAxiError(f"native model: {answer[1:].strip()}")
        tokens = answer.split()
        if len(tokens) != len(full):
            raise NativeAxiError(f"native model answered {len(tokens)} of {len(full)}")
        for (kind, addr, check, reading), token in zip(checks, tokens[:len(queued)],
                                                       strict=True):
            if kind == "W" and check and token != str(OKAY):
                raise AxiResponseError(f"{_RESP_NAMES[int(token)]} writing offset "
                                       f"0x{addr:03X} (deferred)")
            if reading is not None:
                if kind == "R":
                    data, _, resp = token.partition("/")
                    if check and resp and int(resp) != OKAY:
                        raise AxiResponseError(f"{_RESP_NAMES[int(resp)]} reading offset "
                                               f"0x{addr:03X} (deferred)")
                    reading.set(int(data, 16))
                else:
                    reading.set(int(token, 16 if kind == "P" else 10))
        return tokens[len(queued):]

    def _command(self, cmd: str, kind: str = "", addr: int = 0, check: bool = True,
                 reading: Reading | None = None):
        """One command: queued under :meth:`deferred` when ``kind`` (its answer is not
        needed, or goes into ``reading`` when the batch is sent), else sent with the queue;
        its answer (None when queued)."""
        if self._depth and kind:
            self._queue.append(cmd)
            self._checks.append((kind, addr, check, reading))
            return None
        return self._send([cmd])[0]

    @contextlib.contextmanager
    def deferred(self):
        """Queue writes, pushes and runs (whose answers are not needed) and send them as one
        batch: with the next read, poll, wait or :attr:`cycles`, or on leaving the block. A
        queued write that answers SLVERR raises :class:`AxiResponseError` then. Leaving the
        block by an exception drops what is still queued."""
        self._depth += 1
        try:
            yield self
        except BaseException:
            self._depth -= 1
            if not self._depth:
                self._queue, self._checks = [], []
            raise
        self._depth -= 1
        if not self._depth:
            self.flush()

    def flush(self) -> None:
        """Send what :meth:`deferred` has queued."""
        if self._queue:
            self._send([])

    # ------------------------------------------------------------------ commands
    def _addr(self, addr: int) -> int:
        if not 0 <= addr < (1 << self.addr_width):
            raise ValueError(f"address 0x{addr:X} outside the {self.addr_width}-bit bus")
        return addr

    def write(self, addr: int, data: int, strb: int = 0xF, *, check: bool = True):
        """AXI4-Lite write; the bresp (None under :meth:`deferred`). With ``check`` a
        response other than OKAY raises :class:`AxiResponseError`."""
        self._addr(addr)
        if not 0 <= data <= 0xFFFFFFFF or not 0 <= strb <= 0xF:
            raise ValueError(f"write data 0x{data:X} / strobe 0x{strb:X} out of range")
        cmd = f"W {addr:x} {data:x} {strb:x}"
        token = self._command(cmd, "W", addr, check)
        if token is None:
            return None
        resp = int(token)
        if check and resp != OKAY:
            raise AxiResponseError(f"{_RESP_NAMES[resp]} writing offset 0x{addr:03X}")
        return resp

    def read_resp(self, addr: int) -> tuple[int, int]:
        """AXI4-Lite read: (rdata, rresp)."""
        token = self._command(f"R {self._addr(addr):x}")
        data, _, resp = token.partition("/")
        return int(data, 16), int(resp or 0)

    def read(self, addr: int) -> int:
        """AXI4-Lite read; a response other than OKAY raises :class:`AxiResponseError`."""
        data, resp = self.read_resp(addr)
        if resp != OKAY:
            raise AxiResponseError(f"{_RESP_NAMES[resp]} reading offset 0x{addr:03X}")
        return data

    def _stream(self, stream) -> int:
        if isinstance(stream, str):
            if stream not in self.streams:
                raise NativeAxiError(f"no stream {stream!r}; streams: {self.streams}")
            return self.streams.index(stream)
        if not 0 <= stream < len(self.streams):
            raise NativeAxiError(f"no stream {stream}")
        return int(stream)

    def push(self, stream, fields: Mapping[str, object] | int) -> None:
        """Push payloads into an input stream (name or index): a dict of field values (scalars
        for one payload, equal-length arrays for several; packed by
        :func:`navgate.gateware.verify.pack`) or one packed int. Each push waits for ready."""
        k = self._stream(stream)
        fmt = self.formats[self.streams[k]]
        if isinstance(fields, Mapping):
            scalar = all(np.ndim(v) == 0 for v in fields.values())
            arrays = {n: ([v] if scalar else v) for n, v in fields.items()}
            unknown = set(fields) - set(fmt.names)
            if unknown:
                raise ValueError(f"unknown fields {sorted(unknown)}; expected {fmt.names}")
            packed = V.pack(fmt, arrays)
        else:
            packed = [int(fields)]
            if not 0 <= packed[0] < (1 << fmt.width):
                raise ValueError(f"payload does not fit {fmt.width} bits")
        cmds = [f"S {k} {int(p):x}" for p in packed]
        if self._depth:
            for c in cmds:
                self._command(c, "S")
        else:
            self._send(cmds)

    def run(self, cycles: int) -> None:
        """Run ``cycles`` idle clock cycles."""
        if cycles < 0:
            raise ValueError("cycles must be >= 0")
        self._command(f"C {int(cycles)}", "C")

    def poll(self, addr: int, mask: int, value: int, limit: int = 10_000) -> int:
        """Read ``addr`` until ``(rdata & mask) == value`` (at most ``limit`` cycles, else
        :class:`NativeAxiError`); the final rdata."""
        token = self._command(f"P {self._addr(addr):x} {mask & 0xFFFFFFFF:x} "
                              f"{value & 0xFFFFFFFF:x} {int(limit)}")
        return int(token, 16)

    def wait(self, output, limit: int = 10_000) -> int:
        """Run until the watched output (name or index) is high (at most ``limit`` cycles,
        else :class:`NativeAxiError`); the cycles waited (0 if it is high already)."""
        if isinstance(output, str):
            if output not in self.watch:
                raise NativeAxiError(f"output {output!r} is not watched; watched: {self.watch}")
            output = self.watch.index(output)
        return int(self._command(f"Q {int(output)} {int(limit)}"))

    # ------------------------------------------------------------------ answers later
    def read_later(self, addr: int) -> Reading:
        """:meth:`read`, queued under :meth:`deferred` (the :class:`Reading` is filled in
        when the batch is sent; SLVERR raises then), else at once."""
        if not self._depth:
            return Reading(self.read(addr))
        reading = Reading()
        self._command(f"R {self._addr(addr):x}", "R", addr, True, reading)
        return reading

    def poll_later(self, addr: int, mask: int, value: int, limit: int = 10_000) -> Reading:
        """:meth:`poll`, queued under :meth:`deferred` (a timeout raises
        :class:`NativeAxiError` when the batch is sent), else at once."""
        if not self._depth:
            return Reading(self.poll(addr, mask, value, limit))
        reading = Reading()
        self._command(f"P {self._addr(addr):x} {mask & 0xFFFFFFFF:x} "
                      f"{value & 0xFFFFFFFF:x} {int(limit)}", "P", addr, True, reading)
        return reading

    def wait_later(self, output, limit: int = 10_000) -> Reading:
        """:meth:`wait`, queued under :meth:`deferred`, else at once."""
        if not self._depth:
            return Reading(self.wait(output, limit))
        if isinstance(output, str):
            if output not in self.watch:
                raise NativeAxiError(f"output {output!r} is not watched; watched: {self.watch}")
            output = self.watch.index(output)
        if not 0 <= output < len(self.watch):
            raise NativeAxiError(f"no watched output {output}")
        reading = Reading()
        self._command(f"Q {int(output)} {int(limit)}", "Q", 0, True, reading)
        return reading

    @property
    def cycles(self) -> int:
        """Clock cycles simulated since reset (sends what :meth:`deferred` has queued)."""
        if self.proc.poll() is not None and self.final_cycles is not None:
            return self.final_cycles
        return int(self._send(["T"])[0])

    def close(self) -> None:
        """End the process (its total cycle count lands in :attr:`final_cycles`)."""
        if self.proc.poll() is None:
            try:
                _, err = self.proc.communicate("quit\n", timeout=30)
                for ln in err.splitlines():
                    if ln.startswith("cycles "):
                        self.final_cycles = int(ln.split()[1])
            except (OSError, ValueError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()
        for f in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            try:
                f.close()
            except (OSError, ValueError):
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class NativeAxiBus:
    """A bus transport for :class:`navgate.hw.regmap.Registers` over a :class:`NativeAxiSim`
    (``read(offset)``/``write(offset, value)`` at byte offsets from ``base``; SLVERR raises
    :class:`AxiResponseError`, an ``OSError`` as :class:`navgate.hw.bus.MemoryBus` raises).
    Under :meth:`deferred` writes are queued and sent with the next read; :meth:`read_later`
    and :meth:`poll` (what :meth:`Registers.wait_until` uses, in clock cycles) are queued too
    and answer a :class:`~navgate.hw.regmap.Reading`, so a driver's whole job is one round
    trip. The simulation's extras, which a board's bus has not (its sensors are real):
    :meth:`push` into an input stream (a device emulator's samples) and :meth:`wait` for a
    watched output (the interrupt line), both queued under :meth:`deferred`."""

    def __init__(self, sim: NativeAxiSim, base: int = 0):
        self.sim = sim
        self.base = base

    def read(self, offset: int) -> int:
        return self.sim.read(self.base + offset)

    def write(self, offset: int, value: int) -> None:
        self.sim.write(self.base + offset, int(value) & 0xFFFFFFFF)

    def read_later(self, offset: int) -> Reading:
        return self.sim.read_later(self.base + offset)

    def poll(self, offset: int, mask: int, value: int, limit: int) -> Reading:
        return self.sim.poll_later(self.base + offset, mask, value, limit)

    def push(self, stream, fields) -> None:
        self.sim.push(stream, fields)

    def wait(self, output, limit: int = 10_000) -> Reading:
        return self.sim.wait_later(output, limit)

    def deferred(self):
        return self.sim.deferred()


class NativeAxiWindow:
    """A :class:`NativeAxiSim`'s AXI space seen as a board's memory map is: a word-indexed
    window (``w[i]`` reads the 32-bit word at byte ``base + 4 i``, ``w[i] = v`` writes it),
    which :class:`navgate.hw.bus.DevMemBus` takes in place of its ``/dev/mem`` map, so the
    board's code path runs unchanged against the Verilated fabric.

    On a board the fabric runs while the PS's program runs between two bus accesses; here
    the clock stops between batches, so every access first runs ``access_cycles`` idle cycles
    (the time of one access from Python on the Zynq's PS: 100 cycles = 1 us at 100 MHz).
    Each access is one round trip to the native process (no batching: the board's bus has
    none). A bus error (SLVERR) raises :class:`AxiResponseError`, an ``OSError``."""

    def __init__(self, sim: NativeAxiSim, base: int = 0, words: int | None = None, *,
                 access_cycles: int = 100):
        if access_cycles < 0:
            raise ValueError("access_cycles must be >= 0")
        self.sim, self.base, self.access_cycles = sim, int(base), int(access_cycles)
        self.words = ((1 << sim.addr_width) - self.base) // 4 if words is None else int(words)
        #: the bus accesses made through this window
        self.accesses = 0

    def __len__(self) -> int:
        return self.words

    def _addr(self, index) -> int:
        index = int(index)
        if not 0 <= index < self.words:
            raise IndexError(f"word {index} outside the {self.words}-word window")
        return self.base + 4 * index

    def __getitem__(self, index) -> int:
        addr = self._addr(index)
        self.accesses += 1
        _, token = self.sim.batch([f"C {self.access_cycles}", f"R {addr:x}"])
        data, _, resp = token.partition("/")
        if resp and int(resp) != OKAY:
            raise AxiResponseError(f"{_RESP_NAMES[int(resp)]} reading offset 0x{addr:03X}")
        return int(data, 16)

    def __setitem__(self, index, value) -> None:
        addr = self._addr(index)
        self.accesses += 1
        _, token = self.sim.batch([f"C {self.access_cycles}",
                                   f"W {addr:x} {int(value) & 0xFFFFFFFF:x} f"])
        if int(token) != OKAY:
            raise AxiResponseError(f"{_RESP_NAMES[int(token)]} writing offset 0x{addr:03X}")
