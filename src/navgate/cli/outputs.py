"""The one staging path of every command's outputs (README, "Conventions of every command").

A command writes into a staging directory (or file) beside its ``--out`` on the same file
system (:func:`atomic_output_dir`, :func:`atomic_output_file`) and the complete results are
moved into place (plain renames, SIGINT held off) only when the run succeeded. A failed,
interrupted or disk-full run therefore leaves the previous results untouched and no partial
file. No output may be one of the run's inputs (:func:`check_not_input`), nor a device, FIFO,
socket or symbolic link. Each command has its own default output directory
(:func:`default_out_dir`), and ``--out ''`` is an error (:func:`out_option`). Problems with the
output path are found before the long run starts (:func:`check_out_dir`,
:func:`check_writable_file`). Tested in tests/cli/test_bad_input.py and
tests/cli/test_every_command.py.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import click

from navgate.cli.errors import INTERRUPTED, CliError, os_error_message


def default_out_dir(command: str) -> str:
    """Each command's own default output directory (never shared between commands)."""
    return f"navgate-out/{command}"


def reject_empty(ctx, param, value):
    """Click callback of every output option: ``''`` (or blanks) is an error."""
    if value is not None and not str(value).strip():
        raise click.BadParameter("must not be empty")
    return value


def out_option(default: str | None, help: str, kind: str = "dir"):
    """The ``--out`` option of a command: rejects ``''``; ``kind`` is "dir" or "file"."""
    ptype = click.Path(file_okay=(kind == "file"), dir_okay=(kind == "dir"))
    return click.option("--out", "out", type=ptype, default=default, callback=reject_empty,
                         show_default=default is not None, help=help)


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_not_input(path: str | Path, inputs: Iterable[str | Path | None]) -> None:
    """Raise CliError if writing ``path`` would overwrite one of ``inputs``, or would put a
    file inside an input directory (a tile directory: a later run would read it)."""
    p = Path(path)
    for item in inputs:
        if item is None:
            continue
        q = Path(item)
        if _same_file(p, q) or p.resolve() == q.resolve():
            raise CliError(f"output {p} is the input {q}; refusing to overwrite an input")
        if q.is_dir() and p.resolve().is_relative_to(q.resolve()):
            raise CliError(f"output {p} is inside the input directory {q}; refusing to "
                           "write into an input")


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


def check_outputs_early(out: str | Path, names: Iterable[str],
                        inputs: Iterable[str | Path | None]) -> None:
    """Before a long run: ``out`` is not an input (never write into an input directory) and
    no ``out/NAME`` of the files the command will write is one of ``inputs``."""
    inputs = list(inputs)
    check_not_input(out, inputs)
    for name in names:
        check_not_input(Path(out) / name, inputs)


class Staging:
    """Where a run writes: :attr:`dir`, the staging directory of ``--out`` (None when the run
    has no output directory), and :meth:`file`, the staged path of one extra output file."""

    def __init__(self, directory: Path | None, files: dict[Path, Path]):
        self.dir = directory
        self._files = files

    def file(self, final: str | Path) -> Path:
        """The staging path of the extra output ``final`` (as given to :func:`staged_outputs`)."""
        return self._files[Path(final)]


def _check_destination(dest: Path, inputs: list) -> None:
    if dest.is_dir() and not dest.is_symlink():
        raise CliError(f"cannot write {dest}: a directory is in the way")
    _regular_or_absent(dest)
    check_not_input(dest, inputs)


def _stale_files(out: Path | None, replaces: Callable[[Path], bool] | None,
                 produced: dict[Path, Path], inputs: list) -> list[Path]:
    """The files of ``out`` that ``replaces`` selects and this run does not write."""
    if out is None or replaces is None or not out.is_dir():
        return []
    stale = [p for p in sorted(out.iterdir())
             if (p.is_symlink() or not p.is_dir()) and replaces(p)
             and p.resolve() not in produced]
    for path in stale:
        for item in inputs:
            if item is not None and (_same_file(path, Path(item))
                                     or path.resolve() == Path(item).resolve()):
                raise CliError(f"cannot replace the contents of {out}: {path.name} is the "
                               f"input {item}; write to another directory")
    return stale


@contextlib.contextmanager
def staged_outputs(out: str | Path | None = None, files: Iterable[str | Path] = (),
                   inputs: Iterable[str | Path | None] = (), names: Iterable[str] = (),
                   replaces: Callable[[Path], bool] | None = None) -> Iterator[Staging]:
    """The one staging path: yield a :class:`Staging`; commit everything on success.

    ``out`` is an output directory (its staging directory sits beside it), ``files`` are
    extra output files elsewhere (such as ``fly --record FILE``; each staged beside its final
    path). Everything is on the final path's file system, so the commit is a series of
    renames, made with SIGINT held off. On any exception (KeyboardInterrupt and a full disk
    included) the staging is removed and every target is left exactly as it was. Checked
    before the block runs: ``out`` is a directory or absent and not an input, each extra file
    is a regular file or absent and none is an input, nor is ``out/NAME`` for the ``names``
    the command declares it will write (:func:`check_outputs_early`). Checked before anything
    is moved: no destination is a directory, a device, a FIFO or a symbolic link, none is one
    of ``inputs``, and no two outputs share a path. Files already in ``out`` that this run
    does not produce are left alone, except those ``replaces`` selects (a tile directory's
    tiles: the run replaces them as a whole), which are removed in the same commit; an extra
    file the block deleted from its staging path is not committed.
    """
    inputs = list(inputs)
    out = Path(out) if out is not None else None
    finals = [Path(f) for f in files]
    if out is not None:
        check_out_dir(out)
        check_outputs_early(out, names, inputs)
    for final in finals:
        if final.is_dir() and not final.is_symlink():
            raise CliError(f"cannot write {final}: it is a directory")
        _regular_or_absent(final)
        check_not_input(final, inputs)
        _check_ancestors(final, False)
    made: list[Path] = []
    try:
        stage = _stage_beside(out, directory=True) if out is not None else None
        if stage is not None:
            made.append(stage)
        staged = {}
        for final in finals:
            staged[final] = _stage_beside(final, directory=False)
            made.append(staged[final])
        try:
            yield Staging(stage, staged)
        except OSError as error:
            for final, path in ((out, stage), *((f, p) for f, p in staged.items())):
                if path is not None and str(error.filename or "").startswith(str(path)):
                    raise _translate(error, path, final) from None
            if not error.filename:  # a failed flush or close: name what was being written
                targets = [str(t) for t in (out, *staged) if t is not None]
                error.filename = " or ".join(targets) if targets else None
            raise CliError(os_error_message(error)) from None
        moves = []
        if stage is not None:
            moves += [(p, out / p.relative_to(stage))
                      for p in sorted(stage.rglob("*")) if not p.is_dir()]
        moves += [(path, final) for final, path in staged.items() if path.exists()]
        seen: dict[Path, Path] = {}
        for _, dest in moves:
            _check_destination(dest, inputs)
            key = dest.resolve()
            if key in seen:
                raise CliError(f"two outputs of this run would be written to {dest}")
            seen[key] = dest
        stale = _stale_files(out, replaces, seen, inputs)
        try:
            for final, path in staged.items():
                if path.exists():
                    _set_mode(path, final)
            with _sigint_held():
                if out is not None:
                    out.mkdir(parents=True, exist_ok=True)
                for src, dest in moves:
                    dest.parent.mkdir(parents=True, exist_ok=True)
                    os.replace(src, dest)
                for path in stale:
                    path.unlink()
        except OSError as error:
            raise CliError(os_error_message(error)) from None
    finally:
        for path in made:
            _remove(path)


@contextlib.contextmanager
def atomic_output_dir(out: str | Path, inputs: Iterable[str | Path | None] = ()
                      ) -> Iterator[Path]:
    """:func:`staged_outputs` for one output directory: yield its staging directory."""
    with staged_outputs(out, inputs=inputs) as staging:
        yield staging.dir


@contextlib.contextmanager
def atomic_output_file(path: str | Path, inputs: Iterable[str | Path | None] = ()
                       ) -> Iterator[Path]:
    """:func:`staged_outputs` for one output file: yield its staging path (beside it)."""
    with staged_outputs(files=[path], inputs=inputs) as staging:
        yield staging.file(path)


def check_writable_file(path: str | Path) -> Path:
    """Fail early (before any long computation) if ``path`` cannot be written."""
    p = Path(path)
    if p.is_dir():
        raise CliError(f"cannot write {p}: it is a directory")
    _regular_or_absent(p)
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        for ancestor in (parent, *parent.parents):  # the first one that exists says why
            if ancestor.exists() and not ancestor.is_dir():
                raise CliError(f"cannot write {p}: {ancestor} is not a directory")
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
