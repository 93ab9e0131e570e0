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

import numpy as np
from amaranth.lib import wiring

from navgate.gateware import verify as V
from navgate.gateware.native_stream import compile_native
from navgate.hw.regmap import OKAY, Reading

__all__ = ["NativeAxiSim", "NativeAxiBus", "NativeAxiError", "AxiResponseError",
           "build_native_axi"]


class NativeAxiError(RuntimeError):
    """The native model failed to build, rejected a batch, or timed out."""


class AxiResponseError(OSError):
    """A transaction answered SLVERR/DECERR where OKAY was required."""


_RESP_NAMES = {0: "OKAY", 1: "EXOKAY", 2: "SLVERR", 3: "DECERR"}

_MAIN = r"""
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>
#include "V@TOP@.h"
#include "verilated.h"

static const int N_STREAMS = @N_STREAMS@;
static const int N_WATCH = @N_WATCH@;
static const int MAX_WORDS = @MAX_WORDS@;
static const int STREAM_WIDTH[] = {@STREAM_WIDTHS@};
static const uint32_t ADDR_MASK = @ADDR_MASK@u;

static V@TOP@* top;
static long total = 0;
static long limit = 100000;
static double delay_p = 0.0;
static int max_delay = 0;
static int skew = 0;
static uint64_t rng = 0x9E3779B97F4A7C15ull;
static std::string wedged;

static uint64_t next_rand() {  // splitmix64
    uint64_t z = (rng += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static int draw() {
    if (delay_p <= 0.0 || max_delay <= 0) return 0;
    double u = (double)(next_rand() >> 11) * (1.0 / 9007199254740992.0);
    if (u >= delay_p) return 0;
    return 1 + (int)(next_rand() % (uint64_t)max_delay);
}

static void set_stream_valid(int k, int v) {
    switch (k) {
@SET_VALID@
    default: break;
    }
}

static bool stream_ready(int k) {
    switch (k) {
@GET_READY@
    default: return false;
    }
}

static void set_stream_payload(int k, const uint32_t* w) {
    switch (k) {
@SET_PAYLOAD@
    default: break;
    }
}

static bool watched(int k) {
    switch (k) {
@GET_WATCH@
    default: return false;
    }
}

static void idle() {
    top->axi___05Fawvalid = 0; top->axi___05Fwvalid = 0; top->axi___05Fbready = 0;
    top->axi___05Farvalid = 0; top->axi___05Frready = 0;
    for (int k = 0; k < N_STREAMS; k++) set_stream_valid(k, 0);
}

static inline void settle() { top->clk = 0; top->eval(); }
static inline void edge() { top->clk = 1; top->eval(); total++; }

static std::string hex(uint64_t v) {
    char b[32];
    snprintf(b, sizeof b, "%lx", (unsigned long)v);
    return b;
}

static bool axi_write(uint32_t addr, uint32_t data, uint32_t strb, int& resp,
                      std::string& err) {
    int d_aw = draw(), d_w = draw(), d_b = draw();
    if (skew > 0) d_w += skew; else d_aw += -skew;
    top->axi___05Fawaddr = addr & ADDR_MASK; top->axi___05Fawprot = 0;
    top->axi___05Fwdata = data; top->axi___05Fwstrb = strb & 0xF;
    bool aw = false, w = false;
    long start = total;
    while (true) {
        bool both = aw && w;
        top->axi___05Fawvalid = !aw && d_aw == 0;
        top->axi___05Fwvalid = !w && d_w == 0;
        top->axi___05Fbready = both && d_b == 0;
        settle();
        bool aw_f = top->axi___05Fawvalid && top->axi___05Fawready;
        bool w_f = top->axi___05Fwvalid && top->axi___05Fwready;
        bool b_f = top->axi___05Fbready && top->axi___05Fbvalid;
        int r = top->axi___05Fbresp;
        edge();
        if (b_f) { resp = r; idle(); return true; }
        if (aw_f) aw = true; else if (!aw && d_aw) d_aw--;
        if (w_f) w = true; else if (!w && d_w) d_w--;
        if (both && d_b) d_b--;
        if (total - start >= limit) {
            err = std::string("write to 0x") + hex(addr) + ": no " +
                  (!aw ? "AW handshake" : !w ? "W handshake" : "B response") +
                  " within " + std::to_string(limit) + " cycles";
            wedged = err;
            return false;
        }
    }
}

static bool axi_read(uint32_t addr, uint32_t& data, int& resp, std::string& err) {
    int d_ar = draw(), d_r = draw();
    top->axi___05Faraddr = addr & ADDR_MASK; top->axi___05Farprot = 0;
    bool ar = false;
    long start = total;
    while (true) {
        bool was = ar;
        top->axi___05Farvalid = !ar && d_ar == 0;
        top->axi___05Frready = ar && d_r == 0;
        settle();
        bool ar_f = top->axi___05Farvalid && top->axi___05Farready;
        bool r_f = top->axi___05Frready && top->axi___05Frvalid;
        uint32_t d = top->axi___05Frdata;
        int r = top->axi___05Frresp;
        edge();
        if (r_f) { data = d; resp = r; idle(); return true; }
        if (ar_f) ar = true; else if (!ar && d_ar) d_ar--;
        if (was && d_r) d_r--;
        if (total - start >= limit) {
            err = std::string("read of 0x") + hex(addr) + ": no " +
                  (!ar ? "AR handshake" : "R response") + " within " +
                  std::to_string(limit) + " cycles";
            wedged = err;
            return false;
        }
    }
}

static bool push(int k, const uint32_t* w, std::string& err) {
    int d = draw();
    set_stream_payload(k, w);
    long start = total;
    while (true) {
        set_stream_valid(k, d == 0);
        settle();
        bool fire = d == 0 && stream_ready(k);
        edge();
        if (fire) { set_stream_valid(k, 0); return true; }
        if (d) d--;
        if (total - start >= limit) {
            err = "stream " + std::to_string(k) + " not ready within " +
                  std::to_string(limit) + " cycles";
            wedged = err;
            return false;
        }
    }
}

struct Cmd {
    char op;
    uint64_t a, b, c, d;
    std::vector<uint32_t> words;
    std::string text;
};

static bool parse_hex(const std::string& s, uint64_t& v, int max_digits) {
    if (s.empty() || (int)s.size() > max_digits) return false;
    v = 0;
    for (char ch : s) {
        int x;
        if (ch >= '0' && ch <= '9') x = ch - '0';
        else if ((ch | 0x20) >= 'a' && (ch | 0x20) <= 'f') x = (ch | 0x20) - 'a' + 10;
        else return false;
        v = (v << 4) | (uint64_t)x;
    }
    return true;
}

static bool parse_dec(const std::string& s, uint64_t& v) {
    if (s.empty() || s.size() > 18) return false;
    v = 0;
    for (char ch : s) {
        if (ch < '0' || ch > '9') return false;
        v = v * 10 + (uint64_t)(ch - '0');
    }
    return true;
}

static bool parse_words(const std::string& s, int width, std::vector<uint32_t>& w) {
    w.assign(MAX_WORDS, 0);
    int n = s.size();
    if (n == 0) return false;
    for (int i = 0; i < n; i++) {
        char ch = s[n - 1 - i];
        uint32_t x;
        if (ch >= '0' && ch <= '9') x = ch - '0';
        else if ((ch | 0x20) >= 'a' && (ch | 0x20) <= 'f') x = (ch | 0x20) - 'a' + 10;
        else return false;
        if (x == 0) continue;
        int top_bit = 4 * i + (x >= 8 ? 4 : x >= 4 ? 3 : x >= 2 ? 2 : 1);
        if (top_bit > width) return false;
        w[i / 8] |= x << (4 * (i % 8));
    }
    return true;
}

// Parses the whole batch first; an error string for the first bad command.
static std::string parse(const std::vector<std::string>& t, std::vector<Cmd>& cmds) {
    size_t i = 0;
    while (i < t.size()) {
        Cmd c{};
        const std::string& op = t[i];
        c.op = op.size() == 1 ? op[0] : '?';
        size_t need = 0;
        switch (c.op) {
        case 'W': need = 3; break;
        case 'R': need = 1; break;
        case 'S': need = 2; break;
        case 'C': need = 1; break;
        case 'P': need = 4; break;
        case 'Q': need = 2; break;
        case 'T': need = 0; break;
        default: return "unknown command '" + op + "' (token " + std::to_string(i) + ")";
        }
        if (i + need >= t.size())
            return "command " + op + " at token " + std::to_string(i) + " needs " +
                   std::to_string(need) + " arguments";
        c.text = op;
        for (size_t j = 1; j <= need; j++) c.text += " " + t[i + j];
        bool ok = true;
        switch (c.op) {
        case 'W':
            ok = parse_hex(t[i + 1], c.a, 8) && parse_hex(t[i + 2], c.b, 8) &&
                 parse_hex(t[i + 3], c.c, 1);
            break;
        case 'R': ok = parse_hex(t[i + 1], c.a, 8); break;
        case 'S':
            ok = parse_dec(t[i + 1], c.a) && c.a < (uint64_t)N_STREAMS &&
                 parse_words(t[i + 2], STREAM_WIDTH[c.a], c.words);
            break;
        case 'C': ok = parse_dec(t[i + 1], c.a); break;
        case 'P':
            ok = parse_hex(t[i + 1], c.a, 8) && parse_hex(t[i + 2], c.b, 8) &&
                 parse_hex(t[i + 3], c.c, 8) && parse_dec(t[i + 4], c.d);
            break;
        case 'Q': ok = parse_dec(t[i + 1], c.a) && c.a < (uint64_t)N_WATCH &&
                       parse_dec(t[i + 2], c.b); break;
        default: break;
        }
        if (!ok) return "bad arguments in '" + c.text + "'";
        cmds.push_back(c);
        i += need + 1;
    }
    return "";
}

static bool run(const Cmd& c, std::string& ans, std::string& err) {
    switch (c.op) {
    case 'W': {
        int resp;
        if (!axi_write(c.a, c.b, c.c, resp, err)) return false;
        ans = std::to_string(resp);
        return true;
    }
    case 'R': {
        uint32_t d; int resp;
        if (!axi_read(c.a, d, resp, err)) return false;
        ans = hex(d);
        if (resp) ans += "/" + std::to_string(resp);
        return true;
    }
    case 'S':
        if (!push((int)c.a, c.words.data(), err)) return false;
        ans = ".";
        return true;
    case 'C':
        idle();
        for (uint64_t n = 0; n < c.a; n++) { settle(); edge(); }
        ans = ".";
        return true;
    case 'P': {
        long start = total;
        while (true) {
            uint32_t d; int resp;
            if (!axi_read(c.a, d, resp, err)) return false;
            if (resp) {
                err = "poll of 0x" + hex(c.a) + " answered rresp " + std::to_string(resp);
                return false;
            }
            if ((d & c.b) == c.c) { ans = hex(d); return true; }
            if (total - start >= (long)c.d) {
                err = "poll of 0x" + hex(c.a) + " timed out after " +
                      std::to_string(total - start) + " cycles: rdata 0x" + hex(d) +
                      " & mask 0x" + hex(c.b) + " != 0x" + hex(c.c);
                return false;
            }
        }
    }
    case 'Q': {
        idle();
        long start = total;
        while (true) {
            settle();
            if (watched((int)c.a)) { ans = std::to_string(total - start); return true; }
            if (total - start >= (long)c.b) {
                err = "wait for output " + std::to_string(c.a) + " timed out: low for " +
                      std::to_string(c.b) + " cycles";
                return false;
            }
            edge();
        }
    }
    case 'T':
        ans = std::to_string(total);
        return true;
    }
    err = "internal: unknown command";
    return false;
}

int main(int argc, char** argv) {
    for (int i = 1; i + 1 < argc; i += 2) {
        std::string k = argv[i];
        if (k == "--limit") limit = atol(argv[i + 1]);
        else if (k == "--seed")
            rng = strtoull(argv[i + 1], nullptr, 10) * 0x9E3779B97F4A7C15ull + 1;
        else if (k == "--delay-p") delay_p = atof(argv[i + 1]);
        else if (k == "--max-delay") max_delay = atoi(argv[i + 1]);
        else if (k == "--skew") skew = atoi(argv[i + 1]);
        else { std::cerr << "unknown option " << k << "\n"; return 2; }
    }
    std::ios::sync_with_stdio(false);
    top = new V@TOP@;
    idle();
    top->clk = 0; top->rst = 1;
    for (int i = 0; i < 2; i++) { top->clk = 0; top->eval(); top->clk = 1; top->eval(); }
    top->rst = 0;
    std::string line;
    while (std::getline(std::cin, line)) {
        if (line == "quit") break;
        std::vector<std::string> toks;
        std::istringstream ss(line);
        std::string t;
        while (ss >> t) toks.push_back(t);
        if (!wedged.empty()) {
            std::cout << "!wedged by an earlier timeout: " << wedged << '\n' << std::flush;
            continue;
        }
        std::vector<Cmd> cmds;
        std::string perr = parse(toks, cmds);
        if (!perr.empty()) {
            std::cout << "!malformed batch: " << perr << '\n' << std::flush;
            continue;
        }
        std::string out, ans, err;
        bool failed = false;
        for (size_t i = 0; i < cmds.size(); i++) {
            if (!run(cmds[i], ans, err)) {
                std::cout << "!command " << i << " (" << cmds[i].text << "): " << err
                          << '\n' << std::flush;
                failed = true;
                break;
            }
            if (i) out += ' ';
            out += ans;
        }
        if (!failed) std::cout << out << '\n' << std::flush;
    }
    std::cerr << "cycles " << total << "\n";
    delete top;
    return 0;
}
"""


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
    src = _MAIN
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
