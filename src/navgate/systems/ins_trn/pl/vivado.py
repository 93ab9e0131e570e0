"""Seed 000 on the Zybo Z7-20 in Vivado: the block design wrapper and the project script.

``navgate build ins_trn_top --target zybo-z7-20`` writes, beside the Verilog and the XDC:

- ``ins_trn_top_bd.v``: module ``ins_trn_top_bd``, the emitted top under the port names and
  ``X_INTERFACE_INFO`` attributes that Vivado's IP integrator needs to see its buses as
  interfaces when the module is added to a block design as a module reference: ``axi__*``
  becomes the AXI4-Lite slave ``s_axi``, ``dma__*`` the AXI4 write-only master ``m_axi``,
  ``irq`` an interrupt (level high), ``clk_sys`` the clock of both buses; the pin ports keep
  their names (those of the XDC).
- ``ins_trn_top.tcl``: run as ``vivado -mode batch -source ins_trn_top.tcl``. It creates a
  project for the xc7z020clg400-1, adds the Verilog, the wrapper and the XDC, and builds the
  block design ``system``:

  - ``processing_system7`` with the Zybo Z7-20's settings (:data:`PS7_CONFIG`: DDR3L, MIO,
    bank voltages, UART1, SD0, USB0, Ethernet, QSPI; from Digilent's board files, so the
    script needs no board files installed), with M_AXI_GP0, S_AXI_HP0 (32 bits),
    IRQ_F2P and FCLK_RESET0_N enabled;
  - M_AXI_GP0 -> ``axi_interconnect`` (AXI3 -> AXI4-Lite) -> the register bank ``s_axi`` at
    :data:`REGISTER_BASE` (4 KiB);
  - the profile DMA ``m_axi`` -> ``smartconnect`` (AXI4 -> AXI3 bursts) -> S_AXI_HP0, the
    DDR seen at 0 (1 GiB);
  - ``irq`` -> IRQ_F2P[0];
  - clocks: ``clk_sys``, the core's 100 MHz made by its MMCM from the board's 125 MHz
    oscillator (pin K17), clocks M_AXI_GP0_ACLK, S_AXI_HP0_ACLK, both interconnects and
    the reset block. The PS's FCLK_CLK0 is not used: clocking the buses from it would put
    the AXI ports in another clock domain than the register bank behind them (a crossing
    nothing in the fabric handles), while the PS7's AXI ports take any PL clock;
  - resets: ``proc_sys_reset`` (``slowest_sync_clk`` = ``clk_sys``, ``ext_reset_in`` =
    FCLK_RESET0_N) resets the interconnects; the core resets itself from BTN0 and the MMCM's
    lock (``clocking.py``);
  - the board pins as external ports with the XDC's names;

  then the HDL wrapper of the block design (the project's top), synthesis, implementation
  and the bitstream, and copies the PYNQ overlay: ``overlay/ins_trn_top.bit`` and
  ``overlay/ins_trn_top.hwh`` (PYNQ needs both, same base name).

Every port the wrapper and the script name comes from the emitted top's ports
(:func:`navgate.hw.verilog.verilog_ports`), none is typed twice; :func:`cross_check` checks
the written files against the Verilog, and the build refuses to write a script that fails it.
**The script has not been run through Vivado here** (Vivado is not installed): its Tcl syntax
and its file handling are checked with ``tclsh`` and stub Vivado commands
(tests/systems/ins_trn/pl/test_vivado.py), not its meaning to Vivado.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from navgate.hw.verilog import verilog_ports

#: the part of the Zybo Z7-20
PART = "xc7z020clg400-1"
#: where the PS sees the register bank (M_AXI_GP0 starts at 0x4000_0000)
REGISTER_BASE = 0x4000_0000
REGISTER_RANGE = "4K"
#: the fabric clock (ZyboInsTrnTop's MMCM output), Hz
CLK_SYS_HZ = 100_000_000
#: the block design's name and the overlay's base name
BD_NAME = "system"
#: AXI bus prefixes of the emitted top -> (interface name in the wrapper, mode, protocol)
BUSES = {"axi": ("s_axi", "slave", "AXI4LITE"), "dma": ("m_axi", "master", "AXI4")}
#: single-bit ports with an interface of their own
CLOCK_PORT = "clk_sys"
IRQ_PORT = "irq"
#: the board's oscillator pin (K17, 125 MHz; clocking.py) and reset button (BTN0, active high)
BOARD_CLOCK = "clk_in"
BOARD_CLOCK_HZ = 125_000_000
BOARD_RESET = "rst_btn"

#: processing_system7 settings for the Zybo Z7-20 (values from Digilent's Zybo Z7-20 board
#: files, preset rev. A.0 1.2: DDR3L MT41K256M16 32-bit at 533 MHz with the board's trace
#: delays, MIO bank voltages, QSPI, Ethernet, USB0, SD0, UART1 at 115200 baud), plus what
#: this design enables: M_AXI_GP0, S_AXI_HP0 (32-bit), IRQ_F2P and FCLK_RESET0_N.
PS7_CONFIG: dict[str, str] = {
    "PCW_PRESET_BANK0_VOLTAGE": "LVCMOS 3.3V",
    "PCW_PRESET_BANK1_VOLTAGE": "LVCMOS 1.8V",
    "PCW_CRYSTAL_PERIPHERAL_FREQMHZ": "33.333333",
    "PCW_APU_PERIPHERAL_FREQMHZ": "667",
    "PCW_UIPARAM_DDR_ENABLE": "1",
    "PCW_UIPARAM_DDR_MEMORY_TYPE": "DDR 3 (Low Voltage)",
    "PCW_UIPARAM_DDR_PARTNO": "MT41K256M16 RE-125",
    "PCW_UIPARAM_DDR_BUS_WIDTH": "32 Bit",
    "PCW_UIPARAM_DDR_FREQ_MHZ": "533.333333",
    "PCW_UIPARAM_DDR_DRAM_WIDTH": "16 Bits",
    "PCW_UIPARAM_DDR_DEVICE_CAPACITY": "4096 MBits",
    "PCW_UIPARAM_DDR_SPEED_BIN": "DDR3_1066F",
    "PCW_UIPARAM_DDR_BANK_ADDR_COUNT": "3",
    "PCW_UIPARAM_DDR_ROW_ADDR_COUNT": "15",
    "PCW_UIPARAM_DDR_COL_ADDR_COUNT": "10",
    "PCW_UIPARAM_DDR_CL": "7",
    "PCW_UIPARAM_DDR_CWL": "6",
    "PCW_UIPARAM_DDR_T_RCD": "7",
    "PCW_UIPARAM_DDR_T_RP": "7",
    "PCW_UIPARAM_DDR_T_RC": "48.75",
    "PCW_UIPARAM_DDR_T_RAS_MIN": "35.0",
    "PCW_UIPARAM_DDR_T_FAW": "40.0",
    "PCW_UIPARAM_DDR_TRAIN_WRITE_LEVEL": "1",
    "PCW_UIPARAM_DDR_TRAIN_READ_GATE": "1",
    "PCW_UIPARAM_DDR_TRAIN_DATA_EYE": "1",
    "PCW_UIPARAM_DDR_USE_INTERNAL_VREF": "0",
    "PCW_UIPARAM_DDR_BOARD_DELAY0": "0.221",
    "PCW_UIPARAM_DDR_BOARD_DELAY1": "0.222",
    "PCW_UIPARAM_DDR_BOARD_DELAY2": "0.217",
    "PCW_UIPARAM_DDR_BOARD_DELAY3": "0.244",
    "PCW_UIPARAM_DDR_DQS_TO_CLK_DELAY_0": "-0.050",
    "PCW_UIPARAM_DDR_DQS_TO_CLK_DELAY_1": "-0.044",
    "PCW_UIPARAM_DDR_DQS_TO_CLK_DELAY_2": "-0.035",
    "PCW_UIPARAM_DDR_DQS_TO_CLK_DELAY_3": "-0.100",
    "PCW_QSPI_PERIPHERAL_ENABLE": "1",
    "PCW_QSPI_QSPI_IO": "MIO 1 .. 6",
    "PCW_QSPI_GRP_SINGLE_SS_ENABLE": "1",
    "PCW_QSPI_GRP_FBCLK_ENABLE": "1",
    "PCW_ENET0_PERIPHERAL_ENABLE": "1",
    "PCW_ENET0_ENET0_IO": "MIO 16 .. 27",
    "PCW_ENET0_GRP_MDIO_ENABLE": "1",
    "PCW_ENET0_GRP_MDIO_IO": "MIO 52 .. 53",
    "PCW_USB0_PERIPHERAL_ENABLE": "1",
    "PCW_USB0_USB0_IO": "MIO 28 .. 39",
    "PCW_USB0_RESET_ENABLE": "1",
    "PCW_USB0_RESET_IO": "MIO 46",
    "PCW_SD0_PERIPHERAL_ENABLE": "1",
    "PCW_SD0_SD0_IO": "MIO 40 .. 45",
    "PCW_SD0_GRP_CD_ENABLE": "1",
    "PCW_SD0_GRP_CD_IO": "MIO 47",
    "PCW_UART0_PERIPHERAL_ENABLE": "0",
    "PCW_UART1_PERIPHERAL_ENABLE": "1",
    "PCW_UART1_UART1_IO": "MIO 48 .. 49",
    "PCW_UART1_BAUD_RATE": "115200",
    "PCW_GPIO_MIO_GPIO_ENABLE": "1",
    # this design
    "PCW_USE_M_AXI_GP0": "1",
    "PCW_USE_S_AXI_HP0": "1",
    "PCW_S_AXI_HP0_DATA_WIDTH": "32",
    "PCW_USE_FABRIC_INTERRUPT": "1",
    "PCW_IRQ_F2P_INTR": "1",
    "PCW_IRQ_F2P_MODE": "DIRECT",
    "PCW_EN_RST0_PORT": "1",
    "PCW_EN_CLK0_PORT": "0",
}


@dataclass(frozen=True)
class BdPort:
    """A port of the block-design wrapper: its name, the emitted top's port it carries, its
    direction and width, and its bus interface and signal (``s_axi`` / ``AWADDR``) if any."""

    name: str
    core: str
    direction: str
    width: int
    interface: str | None = None
    signal: str | None = None


def bd_ports(verilog_text: str, top: str) -> list[BdPort]:
    """The wrapper's ports, one per port of module ``top`` in the emitted Verilog."""
    ports = []
    for name, direction, width in verilog_ports(verilog_text, top):
        bus, sep, signal = name.partition("__")
        if sep and bus in BUSES:
            interface = BUSES[bus][0]
            ports.append(BdPort(f"{interface}_{signal}", name, direction, width, interface,
                                signal.upper()))
        else:
            ports.append(BdPort(name, name, direction, width))
    missing = [p for p in (CLOCK_PORT, IRQ_PORT) if p not in {q.name for q in ports}]
    if missing:
        raise ValueError(f"module {top} has no port {', '.join(missing)}: not the Zybo variant "
                         "of ins_trn_top (navgate build ins_trn_top --target zybo-z7-20)")
    return ports


def pin_ports(ports: list[BdPort]) -> list[BdPort]:
    """The ports that leave the block design as board pins (the XDC's ports)."""
    return [p for p in ports if p.interface is None and p.name not in (CLOCK_PORT, IRQ_PORT)]


def _vector(width: int) -> str:
    return f"[{width - 1}:0] " if width > 1 else ""


def bd_wrapper(verilog_text: str, top: str) -> str:
    """Verilog of module ``<top>_bd``: ``top`` with interface names and attributes."""
    ports = bd_ports(verilog_text, top)
    lines = [f"// {top}_bd: {top} for a Vivado block design (module reference); generated by",
             "// navgate.systems.ins_trn.pl.vivado from the ports of the emitted top. Not run",
             "// through Vivado by navgate.",
             "`default_nettype none",
             f"module {top}_bd ("]
    decls = []
    # the interface's parameters ride on its first port
    first = {p.interface: p for p in reversed(ports) if p.interface is not None}
    for port in ports:
        attrs = []
        if port.interface is not None:
            attrs.append(f'(* X_INTERFACE_INFO = "xilinx.com:interface:aximm:1.0 '
                         f'{port.interface} {port.signal}" *)')
        elif port.name == CLOCK_PORT:
            buses = ":".join(interface for interface, _, _ in BUSES.values())
            attrs += [f'(* X_INTERFACE_INFO = "xilinx.com:signal:clock:1.0 {CLOCK_PORT} CLK" *)',
                      f'(* X_INTERFACE_PARAMETER = "ASSOCIATED_BUSIF {buses}, '
                      f'FREQ_HZ {CLK_SYS_HZ}" *)']
        elif port.name == BOARD_CLOCK:
            attrs += [f'(* X_INTERFACE_INFO = "xilinx.com:signal:clock:1.0 {BOARD_CLOCK} CLK" *)',
                      f'(* X_INTERFACE_PARAMETER = "FREQ_HZ {BOARD_CLOCK_HZ}" *)']
        elif port.name == BOARD_RESET:
            attrs += [f'(* X_INTERFACE_INFO = "xilinx.com:signal:reset:1.0 {BOARD_RESET} RST" *)',
                      '(* X_INTERFACE_PARAMETER = "POLARITY ACTIVE_HIGH" *)']
        elif port.name == IRQ_PORT:
            attrs += [f'(* X_INTERFACE_INFO = "xilinx.com:signal:interrupt:1.0 {IRQ_PORT} '
                      'INTERRUPT" *)',
                      '(* X_INTERFACE_PARAMETER = "SENSITIVITY LEVEL_HIGH" *)']
        if port.interface is not None and first[port.interface] is port:
            mode, protocol = next((m, pr) for i, m, pr in BUSES.values() if i == port.interface)
            rw = ", READ_WRITE_MODE WRITE_ONLY" if port.interface == "m_axi" else ""
            attrs.append(f'(* X_INTERFACE_PARAMETER = "PROTOCOL {protocol}, '
                         f'FREQ_HZ {CLK_SYS_HZ}{rw}" *)')
        kind = "input" if port.direction == "input" else "output"
        decls.append("".join(f"  {a}\n" for a in attrs)
                     + f"  {kind} wire {_vector(port.width)}{port.name}")
    lines.append(",\n".join(decls))
    lines.append(");")
    connections = ",\n".join(f"    .{p.core}({p.name})" for p in ports)
    lines += [f"  {top} core (", connections, "  );", "endmodule", "`default_nettype wire", ""]
    return "\n".join(lines)


def _tcl_dict(config: dict[str, str]) -> str:
    return " \\\n".join(f"  CONFIG.{key} {{{value}}}" for key, value in config.items())


def vivado_tcl(verilog_text: str, top: str) -> str:
    """The Vivado batch script (module docstring) for the emitted ``top``."""
    ports = bd_ports(verilog_text, top)
    pins = pin_ports(ports)
    port_lines = []
    for port in pins:
        direction = "I" if port.direction == "input" else "O"
        vector = f" -from {port.width - 1} -to 0" if port.width > 1 else ""
        kind = {BOARD_CLOCK: f" -type clk -freq_hz {BOARD_CLOCK_HZ}",
                BOARD_RESET: " -type rst"}.get(port.name, "")
        port_lines.append(f"create_bd_port -dir {direction}{vector}{kind} {port.name}")
        if port.name == BOARD_RESET:  # a reset port is active low unless told
            port_lines.append(f"set_property CONFIG.POLARITY ACTIVE_HIGH "
                              f"[get_bd_ports {port.name}]")
        port_lines.append(f"connect_bd_net [get_bd_ports {port.name}] "
                          f"[get_bd_pins core/{port.name}]")
    ports_tcl = "\n".join(port_lines)
    return f"""\
# {top} on the Digilent Zybo Z7-20 ({PART}): Vivado project, block design, bitstream and
# PYNQ overlay. Generated by navgate (navgate.systems.ins_trn.pl.vivado) from the ports of
# {top}.v. NOT RUN THROUGH VIVADO by navgate: only its Tcl syntax was checked (tclsh).
# Written for Vivado 2020.2 or later (assign_bd_address -offset/-range, PROJ.gen).
# Run:  vivado -mode batch -source {top}.tcl  [-tclargs JOBS]
# Makes: vivado/{top}_zybo (the project), overlay/{top}.bit and overlay/{top}.hwh

set script_dir [file dirname [file normalize [info script]]]
set top {top}
set proj ${{top}}_zybo
set proj_dir [file join $script_dir vivado $proj]
set overlay_dir [file join $script_dir overlay]
set jobs [expr {{[llength $argv] > 0 ? [lindex $argv 0] : 2}}]

create_project $proj $proj_dir -part {PART} -force
add_files -norecurse [list [file join $script_dir ${{top}}.v] [file join $script_dir ${{top}}_bd.v]]
add_files -fileset constrs_1 -norecurse [file join $script_dir ${{top}}.xdc]
update_compile_order -fileset sources_1

create_bd_design {BD_NAME}

# the Zynq PS with the Zybo Z7-20's settings (DDR, MIO) and the ports this design uses
set ps7 [create_bd_cell -type ip -vlnv xilinx.com:ip:processing_system7:5.5 ps7]
set_property -dict [list \\
{_tcl_dict(PS7_CONFIG)} \\
] $ps7
apply_bd_automation -rule xilinx.com:bd_rule:processing_system7 \\
  -config {{make_external "FIXED_IO, DDR" apply_board_preset "0" \\
            Master "Disable" Slave "Disable"}} $ps7

# the core (module reference to the wrapper {top}_bd.v)
set core [create_bd_cell -type module -reference ${{top}}_bd core]

# M_AXI_GP0 -> AXI interconnect (AXI3 -> AXI4-Lite) -> the register bank
set axi_gp [create_bd_cell -type ip -vlnv xilinx.com:ip:axi_interconnect:2.1 axi_gp]
set_property -dict [list CONFIG.NUM_SI {{1}} CONFIG.NUM_MI {{1}}] $axi_gp
connect_bd_intf_net [get_bd_intf_pins ps7/M_AXI_GP0] [get_bd_intf_pins axi_gp/S00_AXI]
connect_bd_intf_net [get_bd_intf_pins axi_gp/M00_AXI] [get_bd_intf_pins core/s_axi]

# the profile DMA -> SmartConnect (AXI4 -> AXI3) -> S_AXI_HP0
set axi_hp [create_bd_cell -type ip -vlnv xilinx.com:ip:smartconnect:1.0 axi_hp]
set_property -dict [list CONFIG.NUM_SI {{1}} CONFIG.NUM_MI {{1}}] $axi_hp
connect_bd_intf_net [get_bd_intf_pins core/m_axi] [get_bd_intf_pins axi_hp/S00_AXI]
connect_bd_intf_net [get_bd_intf_pins axi_hp/M00_AXI] [get_bd_intf_pins ps7/S_AXI_HP0]

# the interrupt
connect_bd_net [get_bd_pins core/{IRQ_PORT}] [get_bd_pins ps7/IRQ_F2P]

# clocks: the core's {CLK_SYS_HZ // 1_000_000} MHz {CLOCK_PORT} (its MMCM, from the 125 MHz pin K17)
# clocks the PS7's AXI ports, both interconnects and the reset block
set rst_sys [create_bd_cell -type ip -vlnv xilinx.com:ip:proc_sys_reset:5.0 rst_sys]
connect_bd_net [get_bd_pins core/{CLOCK_PORT}] \\
  [get_bd_pins ps7/M_AXI_GP0_ACLK] [get_bd_pins ps7/S_AXI_HP0_ACLK] \\
  [get_bd_pins axi_gp/ACLK] [get_bd_pins axi_gp/S00_ACLK] [get_bd_pins axi_gp/M00_ACLK] \\
  [get_bd_pins axi_hp/aclk] [get_bd_pins rst_sys/slowest_sync_clk]

# resets: FCLK_RESET0_N through proc_sys_reset to the interconnects
connect_bd_net [get_bd_pins ps7/FCLK_RESET0_N] [get_bd_pins rst_sys/ext_reset_in]
connect_bd_net [get_bd_pins rst_sys/interconnect_aresetn] \\
  [get_bd_pins axi_gp/ARESETN] [get_bd_pins axi_hp/aresetn]
connect_bd_net [get_bd_pins rst_sys/peripheral_aresetn] \\
  [get_bd_pins axi_gp/S00_ARESETN] [get_bd_pins axi_gp/M00_ARESETN]

# the board pins (names of {top}.xdc)
{ports_tcl}

# addresses: the register bank at 0x{REGISTER_BASE:08X} for the PS; the DDR for the DMA
assign_bd_address -offset 0x{REGISTER_BASE:08X} -range {REGISTER_RANGE} \\
  -target_address_space [get_bd_addr_spaces ps7/Data] [get_bd_addr_segs core/s_axi/reg0]
assign_bd_address -target_address_space [get_bd_addr_spaces core/m_axi] \\
  [get_bd_addr_segs ps7/S_AXI_HP0/HP0_DDR_LOWOCM]

validate_bd_design
save_bd_design

# the HDL wrapper of the block design: the project's top
set bd_file [get_files {BD_NAME}.bd]
generate_target all $bd_file
set wrapper [make_wrapper -files $bd_file -top]
add_files -norecurse $wrapper
set_property top {BD_NAME}_wrapper [current_fileset]
update_compile_order -fileset sources_1

# synthesis, implementation, bitstream
launch_runs synth_1 -jobs $jobs
wait_on_run synth_1
if {{[get_property PROGRESS [get_runs synth_1]] ne "100%"}} {{ error "synthesis failed" }}
launch_runs impl_1 -to_step write_bitstream -jobs $jobs
wait_on_run impl_1
if {{[get_property PROGRESS [get_runs impl_1]] ne "100%"}} {{ error "implementation failed" }}

# the PYNQ overlay: the bitstream and the hardware handoff under one base name
file mkdir $overlay_dir
set bit [file join $proj_dir ${{proj}}.runs impl_1 {BD_NAME}_wrapper.bit]
# (Vivado 2020.2 and later keep it under PROJ.gen, older versions under PROJ.srcs)
set handoff [list sources_1 bd {BD_NAME} hw_handoff {BD_NAME}.hwh]
set hwh [lindex [concat \\
  [glob -nocomplain [file join $proj_dir ${{proj}}.gen {{*}}$handoff]] \\
  [glob -nocomplain [file join $proj_dir ${{proj}}.srcs {{*}}$handoff]]] 0]
if {{$hwh eq ""}} {{ error "no hardware handoff (.hwh) for block design {BD_NAME}" }}
file copy -force $bit [file join $overlay_dir ${{top}}.bit]
file copy -force $hwh [file join $overlay_dir ${{top}}.hwh]
puts "wrote [file join $overlay_dir ${{top}}.bit] and [file join $overlay_dir ${{top}}.hwh]"
"""


#: the overlay files the script writes, relative to the output directory
def overlay_files(top: str) -> tuple[str, str]:
    return (f"overlay/{top}.bit", f"overlay/{top}.hwh")


_ANSI_PORT = re.compile(r"^\s*(input|output) wire (?:\[(\d+):0\] )?(\w+)", re.MULTILINE)


def wrapper_ports(wrapper: str) -> dict[str, tuple[str, int]]:
    """name -> (direction, width) of the wrapper's ANSI port list."""
    start = re.search(r"^module \w+ \(", wrapper, re.MULTILINE)
    if start is None:
        return {}
    header = wrapper[start.end():wrapper.index(");", start.end())]
    return {name: (direction, int(msb) + 1 if msb else 1)
            for direction, msb, name in _ANSI_PORT.findall(header)}


_CORE_PIN = re.compile(r"\bcore/(\w+)")
_BD_PORT = re.compile(r"^create_bd_port -dir ([IO])(?: -from (\d+) -to 0)?(?: -type \w+)?"
                      r"(?: -freq_hz \d+)? (\w+)$", re.MULTILINE)
_INSTANCE_PIN = re.compile(r"^\s*\.(\w+)\((\w+)\)", re.MULTILINE)


def cross_check(tcl: str, wrapper: str, verilog_text: str, top: str) -> list[str]:
    """Mismatches between the script, the wrapper and the emitted Verilog ([] when none):

    - every ``core/NAME`` in the script is a port or an interface of the wrapper;
    - every board port the script creates has the direction and width of the top's port;
    - the wrapper connects every port of the top exactly once, each to a wrapper port of the
      same direction and width, and declares no port the top lacks.
    """
    problems: list[str] = []
    core_ports = {name: (direction, width)
                  for name, direction, width in verilog_ports(verilog_text, top)}
    wrapper_ports_ = wrapper_ports(wrapper)
    interfaces = {interface for interface, _, _ in BUSES.values()}
    for name in sorted(set(_CORE_PIN.findall(tcl))):
        if name not in wrapper_ports_ and name not in interfaces:
            problems.append(f"the script names core/{name}, not a port of {top}_bd")
    for direction, msb, name in _BD_PORT.findall(tcl):
        want = core_ports.get(name)
        got = ("input" if direction == "I" else "output", int(msb) + 1 if msb else 1)
        if want is None:
            problems.append(f"the script makes board port {name}, not a port of {top}")
        elif want != got:
            problems.append(f"board port {name}: script {got}, Verilog {want}")
    connected: dict[str, str] = {}
    for core_port, wrapper_port in _INSTANCE_PIN.findall(wrapper):
        if core_port in connected:
            problems.append(f"{top}.{core_port} connected twice in the wrapper")
        connected[core_port] = wrapper_port
        if core_port not in core_ports:
            problems.append(f"the wrapper connects {core_port}, not a port of {top}")
        elif wrapper_ports_.get(wrapper_port) != core_ports[core_port]:
            problems.append(f"{top}.{core_port} {core_ports[core_port]} connected to "
                            f"{wrapper_port} {wrapper_ports_.get(wrapper_port)}")
    for name in sorted(set(core_ports) - set(connected)):
        problems.append(f"port {name} of {top} is not connected in the wrapper")
    extra = set(wrapper_ports_) - set(connected.values())
    for name in sorted(extra):
        problems.append(f"wrapper port {name} carries no port of {top}")
    return problems


def write_vivado(out_dir: Path, top: str) -> list[Path]:
    """Write ``TOP_bd.v`` and ``TOP.tcl`` beside ``TOP.v`` (already in ``out_dir``)."""
    out_dir = Path(out_dir)
    verilog_text = (out_dir / f"{top}.v").read_text()
    wrapper = bd_wrapper(verilog_text, top)
    tcl = vivado_tcl(verilog_text, top)
    problems = cross_check(tcl, wrapper, verilog_text, top)
    if problems:  # a bug in this module, never the user's: refuse rather than write it
        raise RuntimeError("the Vivado script does not match the Verilog: "
                           + "; ".join(problems))
    paths = [out_dir / f"{top}_bd.v", out_dir / f"{top}.tcl"]
    paths[0].write_text(wrapper)
    paths[1].write_text(tcl)
    return paths
