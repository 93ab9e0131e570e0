"""The Vivado project script and block-design wrapper of ``--target zybo-z7-20``
(navgate.systems.ins_trn.pl.vivado): ports cross-checked against the emitted Verilog, and the
Tcl run by ``tclsh`` with stub Vivado commands (Vivado itself is not here: the script's
meaning to Vivado is not tested, its syntax, ports and file handling are)."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from navgate.systems.ins_trn.pl import vivado

TOP = "ins_trn_top"

#: every Vivado command the script may call, as a stub that logs its call. Tcl's own commands
#: are not stubbed, so a typo in one, or a Vivado command the script calls but this list does
#: not know, fails the run ("invalid command name").
STUBS = r"""
set ::calls {}
proc _log {args} { lappend ::calls $args; return [lindex $args end] }
foreach cmd {create_project add_files update_compile_order create_bd_design set_property
             apply_bd_automation connect_bd_intf_net connect_bd_net create_bd_port
             assign_bd_address validate_bd_design save_bd_design current_fileset get_runs
             launch_runs get_bd_addr_spaces get_bd_addr_segs get_bd_ports get_bd_pins
             get_bd_intf_pins create_bd_cell} {
    proc $cmd {args} "_log $cmd {*}\$args"
}
proc get_files {args} { _log get_files {*}$args; return "system.bd" }
proc make_wrapper {args} { _log make_wrapper {*}$args; return "system_wrapper.v" }
proc get_property {args} { _log get_property {*}$args; return "100%" }
# what Vivado would leave behind: the bitstream after impl_1, the handoff after generate_target
proc wait_on_run {run} {
    _log wait_on_run $run
    if {$run eq "impl_1"} {
        set dir [file join $::proj_dir ${::proj}.runs impl_1]
        file mkdir $dir
        set fh [open [file join $dir system_wrapper.bit] w]; puts $fh bit; close $fh
    }
}
proc generate_target {args} {
    _log generate_target {*}$args
    set dir [file join $::proj_dir ${::proj}.gen sources_1 bd system hw_handoff]
    file mkdir $dir
    set fh [open [file join $dir system.hwh] w]; puts $fh hwh; close $fh
}
set argv {}
if {[catch {source [lindex $::script 0]} error]} { puts stderr "FAILED: $error"; exit 1 }
set fh [open [file join [file dirname [lindex $::script 0]] calls.txt] w]
foreach call $::calls { puts $fh $call }
close $fh
"""


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The Zybo variant's Verilog, XDC and the Vivado files, as ``navgate build`` writes them."""
    from navgate.hw.verilog import emit_verilog
    from navgate.systems.ins_trn.pl.top import InsTrnTop

    out = tmp_path_factory.mktemp("zybo")
    component = InsTrnTop.for_target("zybo-z7-20")
    (out / f"{TOP}.v").write_text(emit_verilog(component, TOP))
    made = component.write_artifacts(out, TOP, target="zybo-z7-20")
    assert {p.name for p in made} >= {f"{TOP}.tcl", f"{TOP}_bd.v", f"{TOP}.xdc"}
    return out


def _texts(out: Path) -> tuple[str, str, str]:
    return ((out / f"{TOP}.tcl").read_text(), (out / f"{TOP}_bd.v").read_text(),
            (out / f"{TOP}.v").read_text())


def test_every_port_in_the_script_and_wrapper_is_a_port_of_the_emitted_top(built):
    from navgate.hw.verilog import verilog_ports
    from navgate.systems.ins_trn.pl.clocking import INPUT_CLOCK_HZ, SYSTEM_CLOCK_HZ

    tcl, wrapper, verilog = _texts(built)
    assert vivado.cross_check(tcl, wrapper, verilog, TOP) == []
    ports = {name: (d, w) for name, d, w in verilog_ports(verilog, TOP)}
    # the buses become interfaces signal for signal; the AXI4-Lite slave has all five channels
    lite = {n[len("axi__"):] for n in ports if n.startswith("axi__")}
    assert lite == {"awaddr", "awprot", "awvalid", "awready", "wdata", "wstrb", "wvalid",
                    "wready", "bresp", "bvalid", "bready", "araddr", "arprot", "arvalid",
                    "arready", "rdata", "rresp", "rvalid", "rready"}
    for name in ports:
        if name.startswith(("axi__", "dma__")):
            interface = "s_axi" if name.startswith("axi__") else "m_axi"
            signal = name.split("__", 1)[1]
            assert (f'aximm:1.0 {interface} {signal.upper()}"' in wrapper
                    and f".{name}({interface}_{signal})" in wrapper), name
    # the board ports of the script are exactly the XDC's ports
    xdc = (built / f"{TOP}.xdc").read_text()
    constrained = set(re.findall(r"get_ports \{ (\w+)(?:\[\d+\])? \}", xdc))
    made = set(re.findall(r"^create_bd_port .* (\w+)$", tcl, re.MULTILINE))
    assert made == constrained
    # buses, interrupt and clock go to the PS7; the clock is the core's, at its frequency
    assert "connect_bd_intf_net [get_bd_intf_pins axi_gp/M00_AXI] [get_bd_intf_pins core/s_axi]" \
        in tcl
    assert "[get_bd_intf_pins axi_hp/M00_AXI] [get_bd_intf_pins ps7/S_AXI_HP0]" in tcl
    assert "connect_bd_net [get_bd_pins core/irq] [get_bd_pins ps7/IRQ_F2P]" in tcl
    assert f"FREQ_HZ {int(SYSTEM_CLOCK_HZ)}" in wrapper
    assert vivado.BOARD_CLOCK_HZ == INPUT_CLOCK_HZ
    assert "-offset 0x40000000" in tcl and "xc7z020clg400-1" in tcl
    assert "NOT RUN THROUGH VIVADO" in tcl


def test_the_cross_check_catches_a_port_typed_twice_wrongly(built):
    """A port renamed or resized in the Verilog, or dropped from the wrapper, is reported."""
    tcl, wrapper, verilog = _texts(built)
    renamed = re.sub(r"\blidar_tx\b", "lidar_txd", verilog)
    problems = vivado.cross_check(tcl, wrapper, renamed, TOP)
    assert any("board port lidar_tx" in p for p in problems), problems
    assert any("connects lidar_tx" in p for p in problems), problems
    assert any("lidar_txd of ins_trn_top is not connected" in p for p in problems), problems
    resized = verilog.replace("output [3:0] led;", "output [4:0] led;")
    assert resized != verilog
    problems = vivado.cross_check(tcl, wrapper, resized, TOP)
    assert any(p.startswith("board port led") for p in problems), problems
    dropped = wrapper.replace("    .irq(irq),\n", "")
    assert dropped != wrapper
    problems = vivado.cross_check(tcl, dropped, verilog, TOP)
    assert "port irq of ins_trn_top is not connected in the wrapper" in problems
    typo = tcl.replace("core/clk_sys", "core/clk_sys0")
    assert "the script names core/clk_sys0, not a port of ins_trn_top_bd" in \
        vivado.cross_check(typo, wrapper, verilog, TOP)


def _tclsh(script: Path) -> subprocess.CompletedProcess:
    tclsh = shutil.which("tclsh")
    if tclsh is None:
        pytest.skip("tclsh (a system package, not on PyPI) is not installed: the Vivado "
                    "script's syntax check needs it")
    stubs = script.parent / "stubs.tcl"
    stubs.write_text(f"set ::script [list {{{script}}}]\n" + STUBS)
    return subprocess.run([tclsh, str(stubs)], capture_output=True, text=True, timeout=60,
                          check=False)


def test_the_script_runs_in_tclsh_with_stub_vivado_commands(built, tmp_path):
    """Syntax, variables and file handling: the script, sourced by tclsh with every Vivado
    command stubbed, ends by copying the overlay's .bit and .hwh under one name."""
    for name in (f"{TOP}.tcl", f"{TOP}.v", f"{TOP}_bd.v", f"{TOP}.xdc"):
        shutil.copy(built / name, tmp_path / name)
    proc = _tclsh(tmp_path / f"{TOP}.tcl")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "overlay" / f"{TOP}.bit").read_text() == "bit\n"
    assert (tmp_path / "overlay" / f"{TOP}.hwh").read_text() == "hwh\n"
    assert [str(tmp_path / f) for f in vivado.overlay_files(TOP)] == \
        [str(tmp_path / "overlay" / f"{TOP}.bit"), str(tmp_path / "overlay" / f"{TOP}.hwh")]
    calls = (tmp_path / "calls.txt").read_text().splitlines()
    assert calls[0].startswith(f"create_project {TOP}_zybo ")
    assert any(c.startswith("launch_runs impl_1 -to_step write_bitstream") for c in calls)
    pins = {m for c in calls for m in re.findall(r"core/(\w+)", c)}
    ports = vivado.wrapper_ports((tmp_path / f"{TOP}_bd.v").read_text())
    assert pins <= set(ports) | {"s_axi", "m_axi"} and {"irq", "clk_sys", "s_axi"} <= pins


def test_the_stub_run_fails_a_broken_script(built, tmp_path):
    """The tclsh check has teeth: an unknown command or an unbalanced brace fails it."""
    tcl = (built / f"{TOP}.tcl").read_text()
    for broken in (tcl.replace("validate_bd_design", "validate_bd_desing"),
                   tcl.replace("if {$hwh eq \"\"} {", "if {$hwh eq \"\"} ")):
        assert broken != tcl
        script = tmp_path / f"{TOP}.tcl"
        script.write_text(broken)
        proc = _tclsh(script)
        assert proc.returncode != 0 and "FAILED" in proc.stderr


def test_navgate_build_says_the_script_was_not_run_through_vivado(monkeypatch, navgate_run,
                                                                  tmp_path):
    """The build's output for a Tcl deliverable: a note that Vivado did not run it, how to run
    it and the overlay it makes (the synthesis itself is replaced: its figures are not what
    this checks)."""
    import navgate.cli.build as build_cli

    def fake_build(name, out_dir, *args, **kwargs):
        for artifact in (f"{name}.tcl", f"{name}_bd.v"):
            (out_dir / artifact).write_text("")
        return {"utilization": {"lut": 1, "ff": 1, "dsp": 0, "carry4": 0, "bram36": 0},
                "latency_cycles": 2, "throughput": "1/696",
                "artifacts": [f"{name}.tcl", f"{name}_bd.v"]}

    monkeypatch.setattr(build_cli, "_run_build", fake_build)
    code, out, err = navgate_run(["build", TOP, "--target", "zybo-z7-20", "--out",
                                  tmp_path / "zybo"])
    assert code == 0, err
    notes = [line for line in err.splitlines() if line.startswith("note:")]
    assert len(notes) == 1, err
    assert "NOT run through Vivado" in notes[0]
    assert f"vivado -mode batch -source {TOP}.tcl" in notes[0]
    assert f"overlay/{TOP}.bit and overlay/{TOP}.hwh" in notes[0]
    assert (tmp_path / "zybo" / f"{TOP}.tcl").is_file()
