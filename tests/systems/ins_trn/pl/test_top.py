"""ins_trn_top's board variant and deliverables (the sigmas COV_POS/VEL/ATT are the output
formatter's, tested in test_output_formatter.py)."""

from __future__ import annotations


def test_zybo_variant_verilog_xdc_and_filelist(tmp_path):
    """``--target zybo-z7-20``: the board variant (MMCM clocking) and its deliverables: every
    pin the XDC constrains is a port of the emitted top, every non-AXI port has a pin, and the
    C header and register docs come from the SystemRDL source."""
    import re

    from navgate.hw.verilog import emit_verilog
    from navgate.systems.ins_trn.pl.board import ZYBO_Z7_20_PINS
    from navgate.systems.ins_trn.pl.top import InsTrnTop, ZyboInsTrnTop

    comp = InsTrnTop.for_target("zybo-z7-20")
    assert isinstance(comp, ZyboInsTrnTop)
    text = emit_verilog(comp, "ins_trn_top")
    header = text[text.index("module ins_trn_top("):]
    header = header[:header.index(");")]
    ports = set(re.findall(r"\b(\w+)\b", header)) - {"module", "ins_trn_top"}
    assert "MMCME2_BASE" in text and "BUFG" in text
    (tmp_path / "ins_trn_top.v").write_text(text)  # as the build flow leaves it
    made = {p.name for p in comp.write_artifacts(tmp_path, "ins_trn_top", target="zybo-z7-20")}
    assert made == {"ins_trn_top_regs.h", "ins_trn_top_regs.md", "ins_trn_top.xdc",
                    "ins_trn_top.f", "ins_trn_top.tcl", "ins_trn_top_bd.v"}
    xdc = (tmp_path / "ins_trn_top.xdc").read_text()
    constrained = set(re.findall(r"get_ports \{ (\w+)(?:\[\d+\])? \}", xdc))
    assert constrained <= ports
    # the buses, the interrupt and the fabric clock go to the block design (vivado.py)
    bus_ports = {p for p in ports if p.startswith(("axi__", "dma__"))} | {"irq", "clk_sys"}
    assert ports - bus_ports == constrained
    for port in constrained:
        pin = ZYBO_Z7_20_PINS[port if port != "led" else "led[0]"][0]
        assert pin in xdc
    assert "create_clock" in xdc and "-period 8.00" in xdc
    header_c = (tmp_path / "ins_trn_top_regs.h").read_text()
    assert "ENG_ADDR" in header_c and "ALT_CTRL" in header_c and "NAV_FLAGS" in header_c
    assert "ins_trn_top.v" in (tmp_path / "ins_trn_top.f").read_text()
    with __import__("pytest").raises(KeyError, match="no variant"):
        InsTrnTop.for_target("arty")
