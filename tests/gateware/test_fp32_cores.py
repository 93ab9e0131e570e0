"""Bit-exact verification of every float32 core against navgate.numerics.fp32.

For each block of ``navgate.gateware.fp32.BLOCKS`` (and the adder in subtract
mode): the special-value cross table and 20,000 biased random vectors in
Amaranth's simulator (half of them under random valid gaps and ready stalls),
20,000 random + directed vectors through the emitted Verilog in Verilator via
cocotb, and (``-m slow``) 100,000 more in Amaranth and 1,000,000 in Verilator.  Zero mismatches are
required; latency and cycle counts are exact.
"""

import numpy as np
import pytest
from amaranth.hdl import Fragment

from navgate.gateware.fp32 import BLOCKS
from navgate.gateware.verify import emit_verilog, lint_verilog, verify
from navgate.gateware.verify_fp32 import CASES, conversion_cases

NAMES = list(CASES)
# random vectors per operation in Amaranth, in two seeded chunks so that pytest-xdist can
# spread them; the second chunk runs under backpressure. 2 x 10,000 in the default suite
# (with the 20,000 in Verilator below); 2 x 50,000 more, other seeds, under -m slow.
BACKPRESSURE = {"valid_prob": 0.9, "ready_prob": 0.85}
CHUNKS = [(0, 10_000, {}), (1, 10_000, BACKPRESSURE)]
SLOW_CHUNKS = [pytest.param(2, 50_000, {}, marks=pytest.mark.slow),
               pytest.param(3, 50_000, BACKPRESSURE, marks=pytest.mark.slow)]


def _check(res):
    assert res.n_vectors > 0
    if not res.ok:
        pytest.fail(res.report())


def test_blocks_registry_constructs_with_defaults():
    assert set(BLOCKS) == {n for n in NAMES if n != "fp32_sub"}
    for name, cls in BLOCKS.items():
        dut = cls()
        Fragment.get(dut, None)  # elaborates with the defaults
        assert isinstance(dut.LATENCY, int) and dut.LATENCY >= 1, name
        assert dut.THROUGHPUT == 1.0, name
        assert dut.LATENCY <= 30, name  # div and sqrt: latency target <= 30


@pytest.mark.parametrize("name", NAMES)
def test_directed_amaranth(name):
    case = CASES[name]
    dut = case.make()
    ins = case.directed()
    res = verify(dut, case.model, ins, formatters=case.formatters, name=name)
    _check(res)
    # No stalls: one vector per cycle plus the pipeline depth, exactly.
    assert res.latency == dut.LATENCY
    assert res.cycles == res.n_vectors + dut.LATENCY


@pytest.mark.parametrize("chunk,n,handshake", CHUNKS + SLOW_CHUNKS,
                         ids=["free", "backpressure", "free-100k", "backpressure-100k"])
@pytest.mark.parametrize("name", NAMES)
def test_random_amaranth(name, chunk, n, handshake):
    case = CASES[name]
    ins = case.random(n, seed=1000 + chunk)
    res = verify(case.make(), case.model, ins, formatters=case.formatters, name=name,
                 seed=chunk, **handshake)
    _check(res)
    assert res.n_vectors == n


@pytest.mark.parametrize("fmt", [(16, 8, 16, 8), (8, 3, 8, 3), (64, 20, 64, 40),
                                 (24, 0, 25, 0), (12, -5, 20, 30), (40, 60, 48, -10)])
def test_conversions_other_q_formats(fmt):
    # 10,000 vectors per format and direction (the default Q16.16 and int32
    # forms get the full 100,000 above).
    for name, case in conversion_cases(*fmt).items():
        for ins in (case.directed(), case.random(10_000, seed=7)):
            _check(verify(case.make(), case.model, ins, formatters=case.formatters,
                          name=f"{name}{fmt}"))


def _concat(a, b):
    return {k: np.concatenate([a[k], b[k]]) for k in a}


@pytest.mark.parametrize("name", NAMES)
def test_verilator(name, tmp_path):
    case = CASES[name]
    ins = _concat(case.directed(), case.random(20_000, seed=2000))
    dut = case.make()
    res = verify(dut, case.model, ins, backend="verilator", formatters=case.formatters,
                 name=name, seed=3, valid_prob=0.95, ready_prob=0.9, work_dir=tmp_path,
                 top=name if name != "fp32_sub" else "fp32_add")
    _check(res)
    assert res.latency == dut.LATENCY


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_verilator_million(name, tmp_path):
    case = CASES[name]
    ins = case.random(1_000_000, seed=3000)
    res = verify(case.make(), case.model, ins, backend="verilator", formatters=case.formatters,
                 name=name, seed=4, valid_prob=0.98, ready_prob=0.98, work_dir=tmp_path,
                 top=name if name != "fp32_sub" else "fp32_add")
    _check(res)
    assert res.n_vectors == 1_000_000


@pytest.mark.parametrize("name", list(BLOCKS))
def test_verilator_lint_clean(name, tmp_path):
    path = tmp_path / f"{name}.v"
    path.write_text(emit_verilog(BLOCKS[name](), name))
    assert lint_verilog(path, top=name) == []
