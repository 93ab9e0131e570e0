"""Seed 000's AXI4-Lite register map, from its one SystemRDL source ``registers.rdl``.

The map is the seed's "AXI Register Map" table (every register at the seed's offset) plus the
extensions the engines need (marked ``navgate_extension`` in the source and listed in
docs/seed000-registers.md): the NED reference point, the TRN fix lag and NIS, the full
covariance diagonal, the calibration matrices and LSBs, and an ID register. The register
bank gateware (:class:`navgate.gateware.axi_lite.AxiLiteRegisterBank`), the C header, the
Markdown documentation and the Python driver are all derived from it
(:mod:`navgate.hw.regmap`).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

from navgate.hw.regmap import RegisterMap, Registers, load_rdl

#: the SystemRDL source of the map
RDL_PATH = Path(__file__).with_name("registers.rdl")
#: the value of the ID register ("NAVG")
ID_VALUE = 0x4E415647
#: the bank's base address on the Zynq's general-purpose AXI port (seed 000)
BASE_ADDRESS = 0x4000_0000


@cache
def register_map() -> RegisterMap:
    """The compiled seed-000 map (compiled once per process)."""
    return load_rdl(RDL_PATH)


def register_bank():
    """The AXI4-Lite register bank of the map (an Amaranth component)."""
    from navgate.gateware.axi_lite import AxiLiteRegisterBank

    return AxiLiteRegisterBank(register_map())


def driver(bus) -> Registers:
    """The Python driver of the map over ``bus``; checks the ID register first."""
    regs = Registers(register_map(), bus)
    found = regs.read("ID")
    if found != ID_VALUE:
        raise OSError(f"no ins_trn register bank on this bus: ID reads 0x{found:08X}, "
                      f"expected 0x{ID_VALUE:08X}")
    return regs
