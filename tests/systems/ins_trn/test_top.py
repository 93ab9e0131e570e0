"""ins_trn_top's own logic: the sigma unit (COV_POS/VEL/ATT) bit-exact to the float32 model on
directed and random diagonals, with its exact latency."""

from __future__ import annotations

import numpy as np
from amaranth.sim import Simulator

from navgate.numerics.fp32 import fp32_add, fp32_sqrt
from navgate.systems.ins_trn.top import SigmaUnit


def _model(diag):
    out = []
    for g in SigmaUnit.GROUPS:
        acc = np.uint32(diag[g[0]])
        for k in g[1:]:
            acc = fp32_add(acc, np.uint32(diag[k]))
        out.append(int(fp32_sqrt(acc)))
    return out


def test_sigma_unit_bit_exact():
    rng = np.random.default_rng(7)
    cases = [np.float32(rng.uniform(0, 1e4, 15)).view(np.uint32) for _ in range(12)]
    cases.append(np.float32(rng.uniform(-1, 1, 15)).view(np.uint32))  # negative sums: NaN
    cases.append(np.full(15, 0x7F800000, np.uint32))  # +inf
    cases.append(np.full(15, 0x00000001, np.uint32))  # subnormals flush to zero
    cases.append(rng.integers(0, 2**32, 15, dtype=np.uint64).astype(np.uint32))
    dut = SigmaUnit()
    got = []

    async def bench(ctx):
        for c in cases:
            for i, v in enumerate(c):
                ctx.set(dut.diag[i], int(v))
            ctx.set(dut.start, 1)
            await ctx.tick()
            ctx.set(dut.start, 0)
            n = 1
            while ctx.get(dut.busy):
                await ctx.tick()
                n += 1
            got.append(([ctx.get(dut.sigma[k]) for k in range(3)], n))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    for c, (sig, n) in zip(cases, got, strict=True):
        want = _model(c)
        assert sig == want or all(
            (s == w) or (np.uint32(s).view(np.float32) != np.uint32(s).view(np.float32)
                         and np.uint32(w).view(np.float32) != np.uint32(w).view(np.float32))
            for s, w in zip(sig, want, strict=True)), (sig, want)
        assert n == dut.LATENCY


def test_zybo_variant_verilog_xdc_and_filelist(tmp_path):
    """``--target zybo-z7-20``: the board variant (MMCM clocking) and its deliverables: every
    pin the XDC constrains is a port of the emitted top, every non-AXI port has a pin, and the
    C header and register docs come from the SystemRDL source."""
    import re

    from navgate.hw.verilog import emit_verilog
    from navgate.systems.ins_trn.board import ZYBO_Z7_20_PINS
    from navgate.systems.ins_trn.top import InsTrnTop, ZyboInsTrnTop

    comp = InsTrnTop().for_target("zybo-z7-20")
    assert isinstance(comp, ZyboInsTrnTop)
    text = emit_verilog(comp, "ins_trn_top")
    header = text[text.index("module ins_trn_top("):]
    header = header[:header.index(");")]
    ports = set(re.findall(r"\b(\w+)\b", header)) - {"module", "ins_trn_top"}
    assert "MMCME2_BASE" in text and "BUFG" in text
    made = {p.name for p in comp.write_artifacts(tmp_path, "ins_trn_top", target="zybo-z7-20")}
    assert made == {"ins_trn_top_regs.h", "ins_trn_top_regs.md", "ins_trn_top.xdc",
                    "ins_trn_top.f"}
    xdc = (tmp_path / "ins_trn_top.xdc").read_text()
    constrained = set(re.findall(r"get_ports \{ (\w+)(?:\[\d+\])? \}", xdc))
    assert constrained <= ports
    bus_ports = {p for p in ports if p.startswith(("axi__", "dma__"))} | {"irq"}
    assert ports - bus_ports == constrained
    for port in constrained:
        pin = ZYBO_Z7_20_PINS[port if port != "led" else "led[0]"][0]
        assert pin in xdc
    assert "create_clock" in xdc and "-period 8.00" in xdc
    header_c = (tmp_path / "ins_trn_top_regs.h").read_text()
    assert "ENG_ADDR" in header_c and "ALT_CTRL" in header_c and "NAV_FLAGS" in header_c
    assert "ins_trn_top.v" in (tmp_path / "ins_trn_top.f").read_text()
    top = InsTrnTop()
    with __import__("pytest").raises(KeyError, match="no variant"):
        top.for_target("arty")
    top._MustUse__silence = True
