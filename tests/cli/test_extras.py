"""navgate.cli.extras: a missing optional package is one line naming the extra, exit 2."""

from __future__ import annotations

import sys

import pytest

from navgate.cli.errors import CliError
from navgate.cli.extras import require


def test_present_module_is_returned():
    assert require("json", "test") is sys.modules["json"]


def test_missing_known_extra_names_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "dask", None)  # import of dask now raises ImportError
    with pytest.raises(CliError) as info:
        require("dask", "navgate campaign")
    msg = str(info.value)
    assert "\n" not in msg
    assert 'navgate[campaign]' in msg and "navgate campaign" in msg


def test_missing_unknown_module_names_pip_package():
    with pytest.raises(CliError, match=r"pip install no_such_mod_xyz$"):
        require("no_such_mod_xyz", "test")


def test_campaign_without_dask_is_one_line_exit_2(monkeypatch, capsys, tmp_path):
    from navgate.cli import main

    monkeypatch.setitem(sys.modules, "dask", None)
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    with pytest.raises(SystemExit) as info:
        main(["campaign", "--seeds", "0-1", "--duration", "10", "--out", str(tmp_path / "o")])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("navgate campaign: error:"), err
    assert "navgate[campaign]" in err[0]
    assert not (tmp_path / "o").exists()
