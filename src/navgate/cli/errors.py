"""Errors of the command line: :class:`CliError` (one line on stderr, exit 2), the OSError
line, the interrupt flag and the co-simulations' own failures.

Every ``navgate`` command raises :class:`CliError` for an expected failure; ``navgate.cli.main``
prints it as one line ``navgate CMD: error: ...`` with exit status 2. An interrupt (Ctrl-C) is
flagged in :data:`INTERRUPTED` (:func:`sigint_flagged`) so that a run whose KeyboardInterrupt
was swallowed or wrapped by a library still never commits its results and exits 130
(README, "Conventions of every command"; tested in tests/cli/test_bad_input.py).
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator


class CliError(Exception):
    """An expected failure (bad input, bad option value): printed as one line, exit 2."""


def os_error_message(error: OSError, what: str = "cannot write") -> str:
    """One line for an OSError: ``cannot write PATH: reason``."""
    reason = error.strerror or str(error) or type(error).__name__
    name = error.filename
    return f"{what} {name}: {reason}" if name else f"{what}: {reason}"


#: set by the command line's SIGINT handler (:func:`install_sigint_flag`): a run that was
#: interrupted never commits its results, even where the KeyboardInterrupt itself was lost
#: (raised inside a compiled numba function it surfaces as a SystemError, and a library may
#: swallow it)
INTERRUPTED = threading.Event()


def _raise_interrupt(*_):
    INTERRUPTED.set()
    raise KeyboardInterrupt


@contextlib.contextmanager
def sigint_flagged() -> Iterator[None]:
    """For one command: :data:`INTERRUPTED` cleared, then SIGINT sets it and raises
    KeyboardInterrupt (main thread only); the previous handler is restored afterwards."""
    INTERRUPTED.clear()
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, _raise_interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def interrupted_by(error: BaseException | None) -> bool:
    """True when ``error`` is, or was caused by, an interrupt (or one was flagged)."""
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, KeyboardInterrupt):
            return True
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return INTERRUPTED.is_set()


def simulation_errors() -> tuple:
    """The gateware co-simulations' own failures (a Verilator build or run that failed) and
    the PL's over its registers (the fabric, simulated or on the board); those whose modules
    this install lacks (a board has no Verilator) cannot be raised and are left out."""
    import importlib

    found = []
    for module, name in (("navgate.gateware.native_axi", "NativeAxiError"),
                         ("navgate.gateware.native_stream", "NativeStreamError"),
                         ("navgate.systems.ins_trn.ps.rtl_engine", "RtlError"),
                         ("navgate.systems.ins_trn.ps.pl_registers", "PlRegisterError")):
        try:
            found.append(getattr(importlib.import_module(module), name))
        except ImportError:
            pass
    return tuple(found)
