"""The ``--engine`` option of the commands that fly seed 000's navigator (``fly``, ``replay``):
its choices come from the PL engines registered in the package metadata
(:mod:`navgate.systems.ins_trn.ps.engine_registry`), and an engine whose package is missing is
one line naming the extra to install."""

from __future__ import annotations

import click

from navgate.cli.errors import CliError


def engine_choice(default: str = "reference"):
    """The ``--engine`` option's type: the PL engines registered in the package metadata
    (:mod:`navgate.systems.ins_trn.ps.engine_registry`), the default first."""
    from navgate.systems.ins_trn.ps.engine_registry import engine_names

    names = engine_names()
    return click.Choice([default] + [n for n in names if n != default])


#: the install extra an engine needs beyond the core (default: the gateware toolchain)
EXTRA_OF = {"board": "board"}


def load_engine_class(engine: str, what: str):
    """The class of ``--engine ENGINE`` (imported now); a missing package is one line."""
    from navgate.systems.ins_trn.ps.engine_registry import engine_class

    try:
        return engine_class(engine)
    except ImportError as error:
        missing = (error.name or "a package").split(".")[0]
        extra = EXTRA_OF.get(engine, "gateware")
        raise CliError(f"{what} --engine {engine} needs the Python package {missing!r}, not "
                       f'installed: pip install "navgate[{extra}]"') from None
