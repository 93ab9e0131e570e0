"""A native Verilator driver for stream components (no cocotb): fast whole-log runs.

The shared harness (:mod:`navgate.gateware.verify`, cocotb) resumes Python on every clock
edge, which limits it to about 10^3-10^4 cycles/s on a loaded machine; seed 003's circuit
needs 388 cycles a sample, so a 13,500-sample log would take hours. This driver compiles
the emitted Verilog with a small C++ testbench that follows the harness's stream rules
(offer the next input while ``i.valid``, take every output with ``o.ready = 1``) and runs
the whole vector file at Verilator speed (Verilator names a port ``i__valid``
``i___05Fvalid`` in C++). It reads and writes the harness's packed format
(:func:`navgate.gateware.verify.pack` / ``unpack``), so results are decoded by the same
code; the tests check it against the cocotb harness and the model on the same vectors.
Compiled models are cached under :func:`navgate.gateware.verify.verilator_cache_dir`.
"""

from __future__ import annotations

import subprocess
import tempfile
import time
from pathlib import Path

from navgate.gateware import verify as V
from navgate.gateware.native_stream import compile_native

__all__ = ["simulate_native", "NativeRun"]

_TB = r"""
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>
#include "V%(top)s.h"
#include "verilated.h"

static const int IN_WORDS = %(in_words)d;

static void set_words(uint32_t* dst, const std::string& hex, int words) {
    for (int k = 0; k < words; k++) dst[k] = 0;
    int n = hex.size();
    for (int i = 0; i < n; i++) {
        char c = hex[n - 1 - i];
        uint32_t v = (c <= '9') ? c - '0' : (c | 0x20) - 'a' + 10;
        dst[i / 8] |= v << (4 * (i %% 8));
    }
}

int main(int argc, char** argv) {
    FILE* fi = fopen(argv[1], "r");
    FILE* fo = fopen(argv[2], "w");
    long limit = atol(argv[3]);
    std::vector<std::string> lines;
    static char buf[8192];
    while (fscanf(fi, "%%8191s", buf) == 1) lines.push_back(buf);
    fclose(fi);
    V%(top)s* top = new V%(top)s;
    uint32_t in[IN_WORDS + 1];
    top->clk = 0; top->rst = 1; top->i___05Fvalid = 0; top->o___05Fready = 1;
    for (int i = 0; i < 2; i++) { top->clk = 0; top->eval(); top->clk = 1; top->eval(); }
    top->rst = 0;
    size_t k = 0, outs = 0;
    long cycles = 0, idle = 0;
    if (k < lines.size()) { set_words(in, lines[k], IN_WORDS); top->i___05Fvalid = 1; }
    while (outs < lines.size()) {
%(set_payload)s
        top->clk = 0; top->eval();
        bool fire_in = top->i___05Fvalid && top->i___05Fready;
        if (top->o___05Fvalid) {
%(get_payload)s
            outs++; idle = 0;
        }
        top->clk = 1; top->eval();
        cycles++; idle++;
        if (fire_in) {
            k++;
            if (k < lines.size()) set_words(in, lines[k], IN_WORDS); else top->i___05Fvalid = 0;
        }
        if (idle > limit) { fprintf(stderr, "no output for %%ld cycles\n", limit); return 3; }
    }
    fprintf(fo, "# cycles %%ld\n", cycles);
    fclose(fo);
    delete top;
    return 0;
}
"""


class NativeRun:
    """Outputs (packed ints), cycles simulated, run and build seconds."""

    def __init__(self, outputs, cycles, seconds, build_seconds):
        self.outputs, self.cycles = outputs, cycles
        self.seconds, self.build_seconds = seconds, build_seconds


def _payload_code(width: int, port: str, write: bool) -> str:
    words = (width + 31) // 32
    if width <= 32:
        return (f"        top->{port} = in[0];" if write else
                f'            fprintf(fo, "%08x\\n", (uint32_t)top->{port});')
    if width <= 64:
        return (f"        top->{port} = ((uint64_t)in[1] << 32) | in[0];" if write else
                f'            fprintf(fo, "%016lx\\n", (unsigned long)top->{port});')
    if write:
        return "\n".join(f"        top->{port}[{i}] = in[{i}];" for i in range(words))
    parts = "".join(f'fprintf(fo, "%08x", (uint32_t)top->{port}[{i}]); '
                    for i in reversed(range(words)))
    return f'            {parts}fprintf(fo, "\\n");'


def _build(verilog_text: str, top: str, in_w: int, out_w: int) -> tuple[Path, float]:
    src_tb = _TB % {"top": top, "in_words": (in_w + 31) // 32,
                    "set_payload": _payload_code(in_w, "i___05Fpayload", True),
                    "get_payload": _payload_code(out_w, "o___05Fpayload", False)}
    t0 = time.perf_counter()
    exe = compile_native(verilog_text, src_tb, top, "native")
    return exe, time.perf_counter() - t0


def simulate_native(component, inputs: dict, *, top: str = "dut",
                    idle_limit: int = 10_000, design: str | None = None,
                    params: dict | None = None) -> tuple[dict, NativeRun]:
    """Stream ``inputs`` (per-field arrays) through ``component`` compiled by Verilator;
    returns the per-field outputs (as :func:`navgate.gateware.verify.simulate`) and a
    :class:`NativeRun`. With ``design`` (and the component's ``params``) the Verilog comes
    from navgate's Verilog cache when it is there (:func:`navgate.gateware.verify.emit_verilog`)."""
    in_fmt = V.stream_format(V._port_shape(component.i))
    out_fmt = V.stream_format(V._port_shape(component.o))
    packed = V.pack(in_fmt, inputs)
    text = V.emit_verilog(component, top, design=design, params=params)
    exe, build_s = _build(text, top, in_fmt.width, out_fmt.width)
    with tempfile.TemporaryDirectory(prefix="navgate-native-") as d:
        fin, fout = Path(d) / "in.hex", Path(d) / "out.hex"
        digits = max(1, (in_fmt.width + 3) // 4)
        fin.write_text("\n".join(format(v, f"0{digits}x") for v in packed) + "\n")
        t0 = time.perf_counter()
        r = subprocess.run([str(exe), str(fin), str(fout), str(idle_limit)],
                           capture_output=True, text=True)
        secs = time.perf_counter() - t0
        if r.returncode != 0:
            raise V.VerifyError(f"native run of {top} failed: {r.stderr[-2000:]}")
        lines = [x for x in fout.read_text().split("\n") if x]
    cycles = int(lines[-1].split()[-1]) if lines and lines[-1].startswith("#") else -1
    outs = [int(x, 16) for x in lines if not x.startswith("#")]
    if len(outs) != len(packed):
        raise V.VerifyError(f"native run returned {len(outs)} results for {len(packed)}")
    return V.unpack(out_fmt, outs), NativeRun(outs, cycles, secs, build_s)
