"""The PL engine registry (systems/ins_trn/ps/engine_registry.py): names from the package
metadata, each loading the class that calls itself by that name, read by the command line."""

import ast
from pathlib import Path

import pytest

from navgate.systems.ins_trn.ps import engine_registry as R
from navgate.systems.ins_trn.ps.pl_interface import PlEngine

PS = Path(R.__file__).parent


def test_every_published_engine_loads_a_pl_engine_of_its_own_name():
    names = R.engine_names()
    assert {"reference", "fp32", "rtl", "fpga-sim"} <= set(names)
    for name in names:
        cls = R.engine_class(name)
        assert issubclass(cls, PlEngine) and cls.name == name


def test_pyproject_publishes_every_engine_under_its_own_name():
    """What pyproject.toml publishes (the installed metadata is a copy made at install time:
    after a change, pip install --no-deps -e . refreshes it), the board engine included."""
    import importlib
    import tomllib

    pyproject = Path(__file__).parents[4] / "pyproject.toml"
    published = tomllib.loads(pyproject.read_text())["project"]["entry-points"][R.ENTRY_POINT_GROUP]
    assert {"reference", "fp32", "rtl", "fpga-sim", "fp32-plain", "board", "rtl-compact",
            "fpga-sim-compact"} == set(published)
    assert published["board"] == "navgate.systems.ins_trn.ps.board_engine:BoardEngine"
    for name, target in published.items():
        module, _, attr = target.partition(":")
        cls = getattr(importlib.import_module(module), attr)
        assert issubclass(cls, PlEngine) and cls.name == name


def test_an_unknown_engine_is_a_value_error_listing_the_names():
    with pytest.raises(ValueError, match="unknown engine 'warp'.*reference"):
        R.engine_class("warp")


def _code_names(path: Path) -> set[str]:
    """Modules imported and string constants used by the code (docstrings left out)."""
    tree = ast.parse(path.read_text())
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef))
                  and node.body and isinstance(node.body[0], ast.Expr)}
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif (isinstance(node, ast.Constant) and isinstance(node.value, str)
              and id(node) not in docstrings):
            names.add(node.value)
    return names


def test_no_module_below_the_engines_names_them():
    """The registry and the engine interface import no engine module, not even by string."""
    for module in ("engine_registry.py", "pl_interface.py"):
        code = " ".join(_code_names(PS / module))
        for engine_module in ("reference_engine", "fp32_engine", "rtl_engine", "fpga_sim",
                              "board_engine"):
            assert engine_module not in code, (module, engine_module)
    tree = ast.parse((PS / "engine_registry.py").read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert not any(m.startswith("navgate") for m in imported if m)


def test_the_command_line_offers_exactly_the_registered_engines():
    from navgate.cli.fly import fly
    from navgate.cli.replay import replay

    for command in (fly, replay):
        option = next(p for p in command.params if p.name == "engine")
        assert sorted(option.type.choices) == sorted(R.engine_names())
        assert option.type.choices[0] == option.default == "reference"
