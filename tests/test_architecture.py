"""The package's import structure (docs/architecture.md): systems import shared libraries, no
shared library imports a system, and no two modules import each other, directly or through
others.

The imports are read from the source with ``ast`` (every ``import`` statement, including those
inside functions), so a lazy import counts as much as a top-level one.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

import navgate

PACKAGE_ROOT = Path(navgate.__file__).parent
SHARED = ("nav", "trn", "numerics", "gateware", "opflow", "devices", "hw", "sim")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE_ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


#: a string naming a navgate module, alone or as "module:attribute" (an import by name)
IMPORT_STRING = re.compile(r"^(navgate(?:\.\w+)+)(?::[\w.]+)?$")


def _launched_modules(tree: ast.AST) -> set[int]:
    """The string nodes that follow ``"-m"`` in a list or tuple: a module run as a child
    process (``python -m navgate.cli ...``), in its own interpreter, not imported here."""
    launched = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.List, ast.Tuple)):
            for before, item in zip(node.elts, node.elts[1:], strict=False):
                if isinstance(before, ast.Constant) and before.value == "-m":
                    launched.add(id(item))
    return launched


def import_graph() -> dict[str, set[str]]:
    """module -> the navgate modules it imports (package imports resolved to modules),
    including those it names in strings for ``importlib`` ("navgate.x.y" or
    "navgate.x.y:attr", as the block registries do)."""
    files = {_module_name(p): p for p in PACKAGE_ROOT.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for module, path in files.items():
        targets: set[str] = set()
        is_package = path.name == "__init__.py"
        tree = ast.parse(path.read_text(), str(path))
        launched = _launched_modules(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                if id(node) in launched:
                    continue
                match = IMPORT_STRING.match(node.value)
                names = [match.group(1)] if match and match.group(1) in files else []
            elif isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(module, is_package, node)
                # "from pkg import mod" imports pkg.mod when that is a module
                names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in files else base
                         for alias in node.names]
            else:
                continue
            targets.update(name for name in names
                           if name == "navgate" or name.startswith("navgate."))
        graph[module] = {t for t in targets if t in files and t != module}
    return graph


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_the_graph_is_read():
    graph = import_graph()
    # a few edges that must be there, so that an empty graph cannot pass the tests below
    assert "navgate.nav.eskf" in graph["navgate.systems.ins_trn.ps.pl_interface"]
    assert "navgate.devices.adis16500" in graph["navgate.nav.calibration"]
    assert "navgate.devices.adis16500" in graph["navgate.sim.sensors"]
    # an import by name (a block registry's "module:attribute" string) is an edge too
    assert "navgate.systems.ins_trn.pl.top" in graph["navgate.systems"]
    assert len(graph) > 60


@pytest.mark.parametrize("shared", SHARED)
def test_shared_libraries_import_no_system(shared):
    offenders = sorted(
        f"{module} -> {target}"
        for module, targets in import_graph().items() if _layer(module) == shared
        for target in targets if _layer(target) in ("systems", "cli")
    )
    assert not offenders, "shared library imports a system or the CLI:\n" + "\n".join(offenders)


#: the TRN modules the scenario may reach: the DEM, for route planning and the ranger's truth
SIM_MAY_IMPORT_FROM_TRN = {"navgate.trn.dem"}
#: the navigator's TRN machinery, which the scenario must not reach even through others
TRN_NAVIGATOR_MODULES = ("navgate.trn.correlators", "navgate.trn.pmf", "navgate.trn.tercom")


def test_the_scenario_imports_no_trn_but_the_dem():
    """sim/ (the scenario) sits below trn/'s navigator parts: its modules import from trn only
    the DEM, and nothing sim reaches, directly or through others, is a correlator, the PMF
    or TERCOM (their settings are the navigator's own, trn_settings.TrnSettings)."""
    graph = import_graph()
    sim = [m for m in graph if _layer(m) == "sim"]
    assert "navgate.sim.flight" in sim
    direct = sorted(f"{m} -> {t}" for m in sim for t in graph[m]
                    if _layer(t) == "trn" and t not in SIM_MAY_IMPORT_FROM_TRN)
    assert not direct, "the scenario imports TRN modules:\n" + "\n".join(direct)
    reached, todo = set(), list(sim)
    while todo:
        for target in graph.get(todo.pop(), ()):
            if target not in reached:
                reached.add(target)
                todo.append(target)
    bad = sorted(m for m in reached if m.startswith(TRN_NAVIGATOR_MODULES))
    assert not bad, "the scenario reaches the navigator's TRN modules: " + ", ".join(bad)


def test_opflow_names_no_system():
    """The op-program toolchain knows no client: no seed, no system package in its text."""
    import re

    files = sorted((PACKAGE_ROOT / "opflow").glob("*.py"))
    assert len(files) >= 3
    pattern = re.compile(r"seed ?\d|systems\.|ins_trn|attitude|kf2x2|gpsins", re.IGNORECASE)
    offenders = [f"{path.name}:{number}: {line.strip()}"
                 for path in files
                 for number, line in enumerate(path.read_text().splitlines(), 1)
                 if pattern.search(line)]
    assert not offenders, "opflow names a client:\n" + "\n".join(offenders)


#: opflow's clients and the toolchain modules each builds on (its program on opflow's IR and
#: executor, its machine from opflow's scheduler and generator)
OPFLOW_CLIENTS = {
    "navgate.systems.ins_trn.pl.fp32_program": {"navgate.opflow.ir"},
    "navgate.systems.ins_trn.pl.nav_engines": {"navgate.opflow.schedule",
                                               "navgate.opflow.machine"},
    "navgate.systems.attitude.program": {"navgate.opflow.ir", "navgate.opflow.execute"},
    "navgate.systems.attitude.datapath": {"navgate.opflow.phased",
                                          "navgate.opflow.phased_machine"},
}
#: the generic parts that live in opflow: a client package must not define them again
OPFLOW_GENERIC = {"Schedule", "ScheduledProgram", "Placed", "ScheduleError", "Builder",
                  "build_schedule", "schedule_banked", "run_bittrue", "PhasedDatapath",
                  "ScheduledMachine"}


def test_opflow_clients_build_on_it():
    """Seed 000's engines and seed 003's circuit take their IR, executor, scheduler and
    machine from opflow (their programs, unit choices and tops stay in systems/), and their
    packages define none of opflow's generic parts again."""
    graph = import_graph()
    missing = sorted(f"{client} -> {target}" for client, targets in OPFLOW_CLIENTS.items()
                     for target in targets - graph.get(client, set()))
    assert not missing, "opflow client without its toolchain import:\n" + "\n".join(missing)
    offenders = []
    for package in ("ins_trn", "attitude"):
        for path in sorted((PACKAGE_ROOT / "systems" / package).rglob("*.py")):
            for node in ast.parse(path.read_text()).body:
                if (isinstance(node, (ast.ClassDef, ast.FunctionDef))
                        and node.name in OPFLOW_GENERIC):
                    offenders.append(f"{path.relative_to(PACKAGE_ROOT)}: {node.name}")
    assert not offenders, "a client defines opflow's generic parts:\n" + "\n".join(offenders)


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan): the import cycles."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return cycles


def test_cycle_finder_finds_a_known_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert find_cycles(graph) == [["a", "b", "c"]]
    assert find_cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles():
    cycles = find_cycles(import_graph())
    assert not cycles, f"import cycles: {cycles}"


# Seed 000 is arranged by computer (../shared/DESIGN.md, Layout): each package may import only
# the packages of seed 000 below it. The fabric knows nothing of its driver or of the Pi.
SEED000_FLOORS = {
    "pl": set(),
    "link": set(),
    "pi": {"link"},
    "ps": {"pl", "link"},
}


def _seed000_part(module: str) -> str | None:
    parts = module.split(".")
    if parts[:3] == ["navgate", "systems", "ins_trn"] and len(parts) > 3:
        return parts[3]
    return None


def test_seed000_is_arranged_by_computer():
    graph = import_graph()
    parts = {_seed000_part(m) for m in graph} - {None}
    assert {"pl", "ps"} <= parts, parts
    offenders = []
    for module, targets in graph.items():
        here = _seed000_part(module)
        if here not in SEED000_FLOORS:
            continue
        for target in targets:
            there = _seed000_part(target)
            if there and there != here and there not in SEED000_FLOORS[here]:
                offenders.append(f"{module} -> {target}")
    assert not offenders, "seed 000 part imports a part it must not:\n" + "\n".join(offenders)


def test_amaranths_private_unused_switch_has_one_user():
    """Amaranth has no public way to mark an elaboratable as intentionally unused; the package
    uses its private switch in one place only (a component whose Verilog came from the cache),
    and refuses bad parameters before a component exists elsewhere (CheckedParameters)."""
    users = sorted(str(p.relative_to(PACKAGE_ROOT)) for p in PACKAGE_ROOT.rglob("*.py")
                   if "_MustUse__silence" in p.read_text(encoding="utf-8"))
    assert users == ["gateware/verify.py"]


#: a seed or one of the seed systems, by number or by package name
_SEED_NAME = re.compile(r"seed[ _-]?00\d|\b(tinykalman|kf2x2|ins_trn|gpsins)\b|systems\.attitude",
                        re.IGNORECASE)


def _code_tokens(source: str):
    """(line, text) of the names and strings of ``source``, docstrings and comments left out."""
    import io
    import tokenize

    doc_lines: set[int] = set()
    for node in ast.walk(ast.parse(source)):
        body = getattr(node, "body", None)
        if (isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)
                and body and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            doc_lines.update(range(body[0].lineno, body[0].end_lineno + 1))
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type in (tokenize.NAME, tokenize.STRING) and tok.start[0] not in doc_lines:
            yield tok.start[0], tok.string


def test_no_code_outside_the_systems_names_a_seed():
    """Outside ``systems/`` (the seeds) and ``cli/`` (their commands), no code names a seed: the
    shared libraries' docstrings and comments cite seed sections as their references, as the
    developers' guide asks, but nothing they do depends on one."""
    found = []
    for path in sorted(PACKAGE_ROOT.rglob("*.py")):
        rel = path.relative_to(PACKAGE_ROOT)
        if rel.parts[0] in ("systems", "cli"):
            continue
        found += [f"{rel}:{line}: {text[:60]}"
                  for line, text in _code_tokens(path.read_text(encoding="utf-8"))
                  if _SEED_NAME.search(text)]
    assert not found, "\n".join(found)


def test_the_seed_name_check_sees_code_and_skips_docstrings():
    source = '"""Seed 000 reference."""\n# seed 001\nX = "kf2x2 block"\n'
    assert [t for _, t in _code_tokens(source) if _SEED_NAME.search(t)] == ['"kf2x2 block"']
