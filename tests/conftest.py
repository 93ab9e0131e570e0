"""Shared test fixtures and paths."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("NAVGATE_SHARED_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """../shared/data (real logs and DEMs); tests using it skip when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data directory {SHARED_DATA} not present")
    return SHARED_DATA


class NavgateRun:
    """``navgate ARGS`` run in-process: ``(exit code, stdout, stderr)``, and the one error
    line a failed command must print (a cold Numba cache's compile notice aside)."""

    def __init__(self, capsys):
        self.capsys = capsys

    def __call__(self, args):
        from navgate.cli import main

        code = 0
        try:
            main([str(a) for a in args])
        except SystemExit as exit_:
            code = exit_.code
        out = self.capsys.readouterr()
        return code, out.out, out.err

    @staticmethod
    def one_line(err: str) -> str:
        lines = [ln for ln in err.splitlines()
                 if ln.strip() and "compiling Numba kernels" not in ln]
        assert len(lines) == 1, err
        assert "Traceback" not in err and "internal error" not in err, err
        return lines[0]


@pytest.fixture
def navgate_run(capsys) -> NavgateRun:
    return NavgateRun(capsys)
