"""Tests of the verification harness itself (navgate.gateware.verify).

The harness must find a wrong result (from a faulty DUT or a wrong model) and
report it, honour backpressure, catch stream-rule violations and stalls, agree
cycle for cycle between Amaranth and Verilator, and cache Verilator builds.
"""

import numpy as np
import pytest
from amaranth.hdl import Module, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware import verify as V


class AddPipe(wiring.Component):
    """r = a + b (8-bit, wrapping) through a 2-stage pipeline that stalls as a whole.

    ``bug``: an input value of ``a`` for which the result is off by one.
    ``ignore_ready``: advance even when the output is not ready (breaks the rules).
    ``dead``: never produce an output.
    """

    LATENCY = 2

    def __init__(self, bug=None, ignore_ready=False, dead=False):
        self.bug, self.ignore_ready, self.dead = bug, ignore_ready, dead
        super().__init__({
            "i": In(stream.Signature(data.StructLayout({"a": unsigned(8), "b": unsigned(8)}))),
            "o": Out(stream.Signature(data.StructLayout({"r": unsigned(8)}))),
        })

    def elaborate(self, platform):
        m = Module()
        en = Signal()
        v1, v2 = Signal(), Signal()
        s1, s2 = Signal(8), Signal(8)
        if self.ignore_ready:
            m.d.comb += en.eq(1)
        else:
            m.d.comb += en.eq(~self.o.valid | self.o.ready)
        m.d.comb += self.i.ready.eq(en)
        total = self.i.payload.a + self.i.payload.b
        if self.bug is not None:
            total = total + (self.i.payload.a == self.bug)
        with m.If(en):
            m.d.sync += [v1.eq(self.i.valid), s1.eq(total), v2.eq(v1), s2.eq(s1)]
        m.d.comb += [self.o.valid.eq(v2 & (0 if self.dead else 1)), self.o.payload.r.eq(s2)]
        return m


def _add_model(x):
    return {"r": (x["a"] + x["b"]) & 0xFF}


def _vectors(n, seed):
    rng = np.random.default_rng(seed)
    return {"a": rng.integers(0, 256, n), "b": rng.integers(0, 256, n)}


def test_pack_unpack_roundtrip_wide_and_signed():
    layout = data.StructLayout({"x": signed(12), "y": unsigned(40), "z": unsigned(20)})
    fmt = V.stream_format(layout)
    assert fmt.width == 72 and fmt.names == ["x", "y", "z"]
    vals = {"x": np.array([-2048, 2047, -1, 0]), "y": np.array([0, (1 << 40) - 1, 12345, 1]),
            "z": np.array([1, 2, (1 << 20) - 1, 0])}
    packed = V.pack(fmt, vals)
    assert packed[1] == 2047 | ((1 << 40) - 1) << 12 | 2 << 52
    assert packed[0] == 0x800 | 1 << 52  # -2048 in 12-bit two's complement
    back = V.unpack(fmt, packed)
    for k in vals:
        np.testing.assert_array_equal(back[k], vals[k])


def test_pack_rejects_missing_field_and_length_mismatch():
    fmt = V.stream_format(data.StructLayout({"a": unsigned(8), "b": unsigned(8)}))
    with pytest.raises(ValueError, match="missing input fields"):
        V.pack(fmt, {"a": np.arange(3)})
    with pytest.raises(ValueError, match="has 2 vectors"):
        V.pack(fmt, {"a": np.arange(3), "b": np.arange(2)})


def test_correct_dut_passes_with_exact_cycle_count():
    n = 500
    res = V.verify(AddPipe(), _add_model, _vectors(n, 1))
    res.assert_ok()
    assert res.n_vectors == n
    # one vector per cycle, plus the pipeline fill: exactly n + LATENCY cycles
    assert res.latency == AddPipe.LATENCY
    assert res.cycles == n + AddPipe.LATENCY


def test_faulty_dut_mismatch_is_reported():
    n = 2000
    vec = _vectors(n, 2)
    bad = np.flatnonzero(vec["a"] == 0x5A)
    assert len(bad) > 2
    res = V.verify(AddPipe(bug=0x5A), _add_model, vec, max_report=3,
                   formatters={"r": lambda v: f"dec {v}"})
    assert not res.ok
    assert res.n_mismatches == len(bad)
    assert [mm.index for mm in res.mismatches] == list(bad[:3])
    first = res.mismatches[0]
    assert first.inputs["a"] == 0x5A
    assert first.got["r"] == (first.expected["r"] + 1) & 0xFF
    text = res.report()
    assert f"vector #{bad[0]}" in text and "a=0x5a" in text
    assert f"expected 0x{first.expected['r']:02x} (dec {first.expected['r']})" in text
    assert f"... {len(bad) - 3} more" in text
    with pytest.raises(AssertionError, match="mismatches"):
        res.assert_ok()


def test_wrong_model_is_reported_for_the_injected_vector():
    vec = _vectors(300, 3)

    def model(x):
        r = _add_model(x)["r"].copy()
        r[123] ^= 0x10
        return {"r": r}

    res = V.verify(AddPipe(), model, vec)
    assert res.n_mismatches == 1 and res.mismatches[0].index == 123


def test_f32_formatter_in_report():
    assert V.f32_formatter(0x3FC00000) == "1.5"
    assert V.f32_formatter(0xFF800000) == "-inf"


@pytest.mark.parametrize("valid_prob,ready_prob", [(0.5, 1.0), (1.0, 0.3), (0.6, 0.5)])
def test_backpressure_keeps_order_and_values(valid_prob, ready_prob):
    n = 800
    vec = _vectors(n, 4)
    res = V.verify(AddPipe(), _add_model, vec, seed=11, valid_prob=valid_prob,
                   ready_prob=ready_prob, keep_outputs=True)
    res.assert_ok()
    np.testing.assert_array_equal(res.outputs["r"], (vec["a"] + vec["b"]) & 0xFF)
    # The whole-pipeline stall throttles to the slower side: at least n / p cycles
    # (minus 5 sigma of the binomial count) are needed.
    p = min(valid_prob, ready_prob)
    assert res.cycles > n / p - 5 * np.sqrt(n * (1 - p)) / p


def test_stream_rule_violation_is_caught():
    with pytest.raises(V.VerifyError, match="stream rule violated"):
        V.verify(AddPipe(ignore_ready=True), _add_model, _vectors(200, 5), ready_prob=0.5)


def test_dead_dut_times_out():
    with pytest.raises(V.VerifyError, match="no output for 50 cycles"):
        V.verify(AddPipe(dead=True), _add_model, _vectors(10, 6), idle_limit=50)


def test_unknown_model_field_rejected():
    dut = AddPipe()
    with pytest.raises(ValueError, match="unknown output fields"):
        V.verify(dut, lambda x: {"q": x["a"]}, _vectors(4, 7))
    dut._MustUse__silence = True  # rejected before simulation, on purpose


def test_verilator_matches_amaranth_cycle_for_cycle(tmp_path):
    vec = _vectors(3000, 8)
    kw = dict(seed=5, valid_prob=0.7, ready_prob=0.6)
    amr = V.verify(AddPipe(bug=0x33), _add_model, vec, **kw)
    vl = V.verify(AddPipe(bug=0x33), _add_model, vec, backend="verilator",
                  work_dir=tmp_path / "run", **kw)
    assert vl.n_mismatches == amr.n_mismatches == int(np.sum(vec["a"] == 0x33)) > 0
    assert [m.index for m in vl.mismatches] == [m.index for m in amr.mismatches]
    assert (vl.cycles, vl.latency) == (amr.cycles, amr.latency)
    assert vl.latency == AddPipe.LATENCY


def test_verilator_detects_stream_rule_violation(tmp_path):
    with pytest.raises(V.VerifyError, match="stream rule violated"):
        V.verify(AddPipe(ignore_ready=True), _add_model, _vectors(200, 9), backend="verilator",
                 ready_prob=0.5, work_dir=tmp_path)


def test_verilator_build_is_cached(tmp_path, monkeypatch):
    """A second build of the same Verilog finds the first one's model without running
    Verilator, and the harness simulates from the cache. The design and top are those of
    test_verilator_matches_amaranth_cycle_for_cycle, so the suite compiles this model once
    (issue 32; it used to build its own in a temporary cache on every run). The first call
    may itself find the model (another test or an earlier run built it); what is checked is
    that the second never builds."""
    text = V.emit_verilog(AddPipe(bug=0x33), "dut")
    first = V._build_model(text, "dut")
    assert (first / "navgate_build.ok").exists() and (first / "dut").exists()
    assert first.name == f"dut-{V.model_key(text, 'dut')}"

    import cocotb_tools.runner

    def no_build(*a, **k):
        raise AssertionError("rebuilt although cached")

    monkeypatch.setattr(cocotb_tools.runner, "get_runner", no_build)
    assert V._build_model(text, "dut") == first
    monkeypatch.undo()
    vec = _vectors(100, 10)
    vec["a"][::7] = 0x33
    res = V.verify(AddPipe(bug=0x33), _add_model, vec, backend="verilator",
                   work_dir=tmp_path / "w")
    assert res.n_mismatches == int(np.sum(vec["a"] == 0x33)) > 0


def test_build_clock_counts_the_children_cpu_and_names_the_test(tmp_path, monkeypatch):
    """The build record (:data:`V.BUILD_RECORD`, read by benchmarks/bench_verilator_models.py)
    holds the CPU seconds of the build's child processes, which a child that burns about
    0.3 s of CPU shows, and the test that asked for the build."""
    import json
    import subprocess
    import sys

    monkeypatch.setenv("PYTEST_CURRENT_TEST", "tests/x.py::test_y (call)")
    burn = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.3: pass"
    with V.build_clock("top", "k" * 24, "cocotb", "module top; endmodule") as record:
        subprocess.run([sys.executable, "-c", burn], check=True)
    V.record_build(tmp_path, record)
    got = json.loads((tmp_path / V.BUILD_RECORD).read_text())
    assert got["cpu_s"] >= 0.29 and got["wall_s"] >= 0.29
    assert got["test"] == "tests/x.py::test_y" and got["top"] == "top"
    assert got["verilog_bytes"] == len("module top; endmodule")
    V.record_build(tmp_path / "absent", record)  # a model dir that vanished: no error


def test_lint_reports_unwaived_warning_and_passes_clean_code(tmp_path):
    bad = tmp_path / "bad.v"
    bad.write_text(
        "module bad(input clk, input a, output reg q);\n"
        "  always @(posedge clk) q = a;\n"  # blocking assignment in a clocked block
        "endmodule\n")
    issues = V.lint_verilog(bad)
    assert any("BLKSEQ" in line for line in issues), issues
    good = tmp_path / "addpipe.v"
    good.write_text(V.emit_verilog(AddPipe(), "addpipe"))
    assert V.lint_verilog(good) == []


def test_native_back_end_refuses_random_gaps_and_verify_names_it():
    """``native_stream.simulate_native_stream`` as ``verify``'s back end: random valid/ready
    gaps are refused before anything is built (the native server offers every input at
    once); an unknown back-end name is refused too."""
    from navgate.gateware.native_stream import simulate_native_stream

    duts = [AddPipe(), AddPipe()]
    for dut in duts:
        V.not_elaborated(dut)  # refused before elaboration
    with pytest.raises(ValueError, match="random valid/ready gaps"):
        V.verify(duts[0], _add_model, _vectors(10, 1), backend=simulate_native_stream,
                 ready_prob=0.5)
    with pytest.raises(ValueError, match="unknown backend 'icarus'"):
        V.verify(duts[1], _add_model, _vectors(10, 1), backend="icarus")
