"""Shared pieces of the command line: errors, output safety, console and warning conventions.

Conventions every ``navgate`` command follows (issue 17; tested in tests/cli/test_bad_input.py):

- **Errors** are :class:`CliError`: one line on stderr, exit status 2. Any ``OSError`` on
  output is turned into such a line (:func:`os_error_message`).
- **Output safety.** A command writes into a staging directory beside its ``--out``
  (:func:`atomic_output_dir`, :func:`atomic_output_file`, same file system) and moves the
  complete results into place only when the run succeeded, with SIGINT held off during the
  moves (plain renames). A failed, interrupted or disk-full run therefore leaves the
  previous results untouched and no partial file. No output may be one of the run's inputs.
  Each command has its own default output directory (:func:`default_out_dir`), and
  ``--out ''`` is an error (:func:`out_option`).
- **Console.** Result tables go to stdout, progress, notes and "wrote ..." lines to stderr
  (:func:`consoles`); ``--quiet`` hides the table and the progress, never errors or warnings.
- **Warnings** from libraries (NumPy, rasterio, ...) are shown as one line each, in navgate's
  words, prefixed ``navgate CMD: warning:`` (:func:`warning_handler`).
- The "compiling Numba kernels" note is printed only when Numba compiles (:func:`numba_note`).
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import shutil
import signal
import tempfile
import threading
import warnings
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import click


class CliError(Exception):
    """An expected failure (bad input, bad option value): printed as one line, exit 2."""


# ---------------------------------------------------------------------------------------------
# output paths


def default_out_dir(command: str) -> str:
    """Each command's own default output directory (never shared between commands)."""
    return f"navgate-out/{command}"


def _reject_empty(ctx, param, value):
    if value is not None and not str(value).strip():
        raise click.BadParameter("must not be empty")
    return value


def out_option(default: str | None, help: str, kind: str = "dir"):
    """The ``--out`` option of a command: rejects ``''``; ``kind`` is "dir" or "file"."""
    ptype = click.Path(file_okay=(kind == "file"), dir_okay=(kind == "dir"))
    return click.option("--out", "out", type=ptype, default=default, callback=_reject_empty,
                         show_default=default is not None, help=help)


def os_error_message(error: OSError, what: str = "cannot write") -> str:
    """One line for an OSError: ``cannot write PATH: reason``."""
    reason = error.strerror or str(error) or type(error).__name__
    name = error.filename
    return f"{what} {name}: {reason}" if name else f"{what}: {reason}"


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_not_input(path: str | Path, inputs: Iterable[str | Path | None]) -> None:
    """Raise CliError if writing ``path`` would overwrite one of ``inputs``."""
    p = Path(path)
    for item in inputs:
        if item is None:
            continue
        q = Path(item)
        if _same_file(p, q) or p.resolve() == q.resolve():
            raise CliError(f"output {p} is the input {q}; refusing to overwrite an input")


def _set_mode(stage: Path, path: Path) -> None:
    """Give the staged file the mode a plain ``open(path, "w")`` would have given it (the
    existing file's, else 0666 less the umask), not mkstemp's 0600."""
    if path.exists():
        mode = path.stat().st_mode & 0o7777
    else:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask
    os.chmod(stage, mode)


def _regular_or_absent(path: Path) -> None:
    """Outputs replace regular files only (never a device, FIFO or socket such as /dev/full)."""
    if path.is_symlink():
        raise CliError(f"cannot write {path}: it is a symbolic link")
    if path.exists() and not path.is_file():
        raise CliError(f"cannot write {path}: not a regular file")


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


@contextlib.contextmanager
def _sigint_held() -> Iterator[None]:
    """Defer SIGINT for the duration of the block (main thread only), then deliver it; an
    interrupt flagged earlier (:data:`INTERRUPTED`) stops the block before it starts."""
    if INTERRUPTED.is_set():
        raise KeyboardInterrupt
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []

    def hold(*a):
        INTERRUPTED.set()
        caught.append(a)

    previous = signal.signal(signal.SIGINT, hold)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if caught:
            raise KeyboardInterrupt


def check_out_dir(out: str | Path) -> Path:
    """Fail early (before a long run prints anything) when ``out`` cannot be a directory."""
    target = Path(out)
    if target.exists() and not target.is_dir():
        raise CliError(f"output path {target} exists and is not a directory")
    _check_ancestors(target, True)
    return target


def _check_ancestors(target: Path, directory: bool) -> None:
    what = "cannot create output directory" if directory else "cannot write"
    for ancestor in (target, *target.parents) if directory else target.parents:
        if ancestor.exists() or ancestor.is_symlink():
            if not ancestor.is_dir() and ancestor != target:
                raise CliError(f"{what} {target}: {ancestor} is not a directory")
            break


def _stage_beside(target: Path, directory: bool) -> Path:
    parent = target.parent
    what = "cannot create output directory" if directory else "cannot write"
    _check_ancestors(target, directory)
    try:
        parent.mkdir(parents=True, exist_ok=True)
        prefix = f".{target.name}.navgate-tmp-"
        if directory:
            return Path(tempfile.mkdtemp(prefix=prefix, dir=parent))
        fd, name = tempfile.mkstemp(prefix=prefix, dir=parent)
        os.close(fd)
        return Path(name)
    except OSError as error:
        raise CliError(f"{what} {target}: {error.strerror or error}") from None


def _remove(path: Path) -> None:
    with contextlib.suppress(OSError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()


def _translate(error: OSError, stage: Path, final: Path) -> CliError:
    """An OSError raised while writing into ``stage``, named by its final path."""
    name = str(error.filename or "")
    if name.startswith(str(stage)):
        error.filename = str(final) + name[len(str(stage)):]
    return CliError(os_error_message(error))


@contextlib.contextmanager
def atomic_output_dir(out: str | Path, inputs: Iterable[str | Path | None] = ()
                      ) -> Iterator[Path]:
    """Yield a staging directory; on success move everything in it into ``out``.

    The staging directory sits beside ``out`` (same file system, so the final moves are
    renames). On any exception (including KeyboardInterrupt and a full disk) the staging
    directory is removed and ``out`` is left exactly as it was. Before anything is moved,
    every destination is checked: none may be a directory where a file goes, nor one of
    ``inputs``. Files already in ``out`` that this run does not produce are left alone.
    """
    out = Path(out)
    inputs = list(inputs)
    if out.exists() and not out.is_dir():
        raise CliError(f"output path {out} exists and is not a directory")
    stage = _stage_beside(out, directory=True)
    try:
        try:
            yield stage
        except OSError as error:
            raise _translate(error, stage, out) from None
        files = sorted(p for p in stage.rglob("*") if not p.is_dir())
        moves = [(p, out / p.relative_to(stage)) for p in files]
        for _, dest in moves:
            if dest.is_dir():
                raise CliError(f"cannot write {dest}: a directory is in the way")
            _regular_or_absent(dest)
            check_not_input(dest, inputs)
        try:
            with _sigint_held():
                out.mkdir(parents=True, exist_ok=True)
                for src, dest in moves:
                    dest.parent.mkdir(parents=True, exist_ok=True)
                    os.replace(src, dest)
        except OSError as error:
            raise _translate(error, stage, out) from None
    finally:
        _remove(stage)


@contextlib.contextmanager
def atomic_output_file(path: str | Path, inputs: Iterable[str | Path | None] = ()
                       ) -> Iterator[Path]:
    """Yield a temporary file path beside ``path``; on success rename it onto ``path``."""
    path = Path(path)
    if path.is_dir():
        raise CliError(f"cannot write {path}: it is a directory")
    _regular_or_absent(path)
    check_not_input(path, inputs)
    stage = _stage_beside(path, directory=False)
    try:
        try:
            yield stage
        except OSError as error:
            raise _translate(error, stage, path) from None
        try:
            _set_mode(stage, path)
            with _sigint_held():
                os.replace(stage, path)
        except OSError as error:
            raise _translate(error, stage, path) from None
    finally:
        _remove(stage)


def check_writable_file(path: str | Path) -> Path:
    """Fail early (before any long computation) if ``path`` cannot be written."""
    p = Path(path)
    if p.is_dir():
        raise CliError(f"cannot write {p}: it is a directory")
    _regular_or_absent(p)
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise CliError(f"cannot write {p}: directory {parent} does not exist")
    if p.exists() and not os.access(p, os.W_OK):
        raise CliError(f"cannot write {p}: permission denied")
    try:  # the real test: create (and remove) a file beside it, as the atomic write will
        fd, probe = tempfile.mkstemp(prefix=f".{p.name}.navgate-probe-", dir=parent)
        os.close(fd)
        os.unlink(probe)
    except OSError as error:
        raise CliError(f"cannot write {p}: {error.strerror or error}") from None
    return p


def prepare_out_dir(path: str | Path) -> Path:
    """Create the output directory (and parents), failing with a clear CliError."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise CliError(f"cannot create output directory {out}: {error.strerror}") from None
    if not out.is_dir():
        raise CliError(f"output path {out} exists and is not a directory")
    return out


# ---------------------------------------------------------------------------------------------
# summaries


def _json_ready(value: Any) -> Any:
    """Convert NumPy scalars/arrays and non-finite floats into plain JSON values.

    A dictionary entry whose value is ``None`` (not applicable to this run, such as the NIS
    of a run without TRN fixes) is left out: a summary never holds ``null`` for "does not
    apply"; the key is absent (docs/conventions.md). Non-finite floats become ``null`` so
    the file stays valid JSON, and the commands then fail (:func:`non_finite_keys`).
    """
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, dict):
        return {str(k): _json_ready(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def non_finite_keys(summary: Any, prefix: str = "") -> list[str]:
    """Dotted keys of every NaN/inf float in ``summary`` (for the no-silent-NaN rule)."""
    if hasattr(summary, "tolist"):
        summary = summary.tolist()
    found = []
    if isinstance(summary, dict):
        for k, v in summary.items():
            found += non_finite_keys(v, f"{prefix}{k}.")
    elif isinstance(summary, (list, tuple)):
        for i, v in enumerate(summary):
            found += non_finite_keys(v, f"{prefix}{i}.")
    elif isinstance(summary, float) and not math.isfinite(summary):
        found.append(prefix.rstrip("."))
    return found


def write_summary(out_dir: Path, summary: dict[str, Any], name: str = "summary.json") -> Path:
    """Write a run's machine-readable summary beside its report."""
    path = Path(out_dir) / name
    path.write_text(json.dumps(_json_ready(summary), indent=2, sort_keys=False) + "\n")
    return path


# ---------------------------------------------------------------------------------------------
# console


def consoles(quiet: bool = False):
    """(stdout console for result tables, stderr console for progress/notes); quiet hides
    both (errors and warnings are printed by :func:`navgate.cli.main`, not through them)."""
    from rich.console import Console

    return Console(quiet=quiet), Console(stderr=True, quiet=quiet, soft_wrap=True)


@contextlib.contextmanager
def numba_note(console) -> Iterator[None]:
    """Within the block, print the compile note once, and only when Numba starts compiling a
    kernel (Numba's ``numba:compile`` event), so that a cached run prints nothing and a
    first run's bar standing still says why."""
    try:
        from numba.core import event
    except ImportError:  # pragma: no cover
        yield
        return
    shown = []

    class _Note(event.Listener):
        def on_start(self, ev):
            if not shown:
                shown.append(True)
                console.print("compiling Numba kernels (first run only, up to a minute; "
                              "cached afterwards)", style="dim")

        def on_end(self, ev):
            pass

    with event.install_listener("numba:compile", _Note()):
        yield


# ---------------------------------------------------------------------------------------------
# warnings

#: (category name or message fragment, navgate's words); first match wins
_WARNING_WORDS = (
    ("NotGeoreferencedWarning", "the DEM file has no georeferencing; its coordinates are "
                                "not usable"),
    ("invalid value encountered", "a computation produced NaN (invalid value)"),
    ("divide by zero", "a computation divided by zero"),
    ("overflow encountered", "a computation overflowed"),
    ("Mean of empty slice", "a mean over no samples (result is NaN)"),
)


def warning_line(prefix: str, message: Any, category: type | None = None) -> str:
    """One line in navgate's words for a library warning."""
    text = " ".join(str(message).split())
    cat = category.__name__ if category is not None else ""
    for key, words in _WARNING_WORDS:
        if key == cat or key in text:
            return f"{prefix}: warning: {words} ({text[:160]})" if key != cat else \
                f"{prefix}: warning: {words}"
    return f"{prefix}: warning: {text[:240]}"


class _OneLineHandler(logging.Handler):
    def __init__(self, prefix: str):
        super().__init__(logging.WARNING)
        self.prefix = prefix

    def emit(self, record):  # pragma: no cover - exercised through library logging
        with contextlib.suppress(Exception):
            click.echo(warning_line(self.prefix, record.getMessage()), err=True)


@contextlib.contextmanager
def warning_handler(prefix: str) -> Iterator[None]:
    """Within the block, Python warnings and library log records (WARNING and above) are
    printed as one line each in navgate's words, each distinct line once."""
    seen: set[str] = set()

    def show(message, category, filename, lineno, file=None, line=None):
        text = warning_line(prefix, message, category)
        if text not in seen:
            seen.add(text)
            click.echo(text, err=True)

    root = logging.getLogger()
    handler = _OneLineHandler(prefix)
    level = root.level
    with warnings.catch_warnings():
        # library API deprecations are for navgate's developers, not its users
        for category in (DeprecationWarning, PendingDeprecationWarning, FutureWarning):
            warnings.simplefilter("ignore", category)
        # Amaranth's notice that a component object was garbage-collected without being
        # elaborated says nothing to a user (it comes from whatever object the collector
        # happens to reach, even one made by an earlier call in the same process)
        warnings.filterwarnings("ignore", message=r".*created but never used")
        warnings.showwarning = show
        root.addHandler(handler)
        if level == logging.NOTSET or level > logging.WARNING:
            root.setLevel(logging.WARNING)
        try:
            yield
        finally:
            root.removeHandler(handler)
            root.setLevel(level)


def engine_choice(default: str = "reference"):
    """The ``--engine`` option's type: the PL engines registered in the package metadata
    (:mod:`navgate.systems.ins_trn.ps.engine_registry`), the default first."""
    from navgate.systems.ins_trn.ps.engine_registry import engine_names

    names = engine_names()
    return click.Choice([default] + [n for n in names if n != default])


def load_engine_class(engine: str, what: str):
    """The class of ``--engine ENGINE`` (imported now); a missing package is one line."""
    from navgate.systems.ins_trn.ps.engine_registry import engine_class

    try:
        return engine_class(engine)
    except ImportError as error:
        missing = (error.name or "a package").split(".")[0]
        raise CliError(f"{what} --engine {engine} needs the Python package {missing!r}, not "
                       f'installed: pip install "navgate[gateware]"') from None


def simulation_errors() -> tuple:
    """The gateware co-simulations' own failures (a Verilator build or run that failed)."""
    from navgate.gateware.native_axi import NativeAxiError
    from navgate.gateware.native_stream import NativeStreamError
    from navgate.systems.ins_trn.ps.fpga_sim import FpgaSimError
    from navgate.systems.ins_trn.ps.rtl_engine import RtlError

    return (NativeStreamError, RtlError, NativeAxiError, FpgaSimError)


def hardware_line(hw: dict) -> str:
    """One line of a simulated PL's counts (summary "hardware")."""
    if "simulated_cycles" in hw:
        return (f"{hw['simulated_cycles'] / 1e6:.1f} M cycles simulated "
                f"({hw['cycles_per_imu_sample']:,.0f} per IMU sample), "
                f"{hw['update_interrupts']:,} update interrupts, "
                f"{hw['profile_dmas']:,} profile DMAs, "
                f"{hw['baro_samples_through_pins']:,} barometer samples and "
                f"{hw['ranger_frames_through_pins']:,} ranger frames through the pins")
    return (f"{hw['engine_cycles'] / 1e6:.1f} M engine cycles "
            f"({hw['engine_cycles_per_imu_sample']:,.0f} per IMU sample)")
