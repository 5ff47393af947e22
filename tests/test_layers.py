"""The architecture holds: import-layer contracts (pyproject's [tool.importlinter]) and no family named in code."""

from __future__ import annotations

import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest

import hil
from hil.bench.family import families
from tests.conftest import REPO


def test_import_contracts_are_kept() -> None:
    """Layers point down only, families are independent, no package imports its siblings in a cycle."""
    lint = Path(sys.executable).parent / "lint-imports"
    proc = subprocess.run([str(lint), "--no-cache"], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "4 kept, 0 broken" in proc.stdout


def test_no_code_compares_a_family_name() -> None:
    """A family is a plug-in found by name in the registry; no module decides by comparing the name."""
    holder = r"(profile|given|bench|emulator|emu|self|plugin)\.family"
    pattern = re.compile(rf"{holder}\s*[!=]=|[!=]=\s*{holder}\b"
                         r"|[!=]=\s*[\"'](fbs|s7-200smart)[\"']|[\"'](fbs|s7-200smart)[\"']\s*[!=]=")
    hits = [f"{path.relative_to(REPO)}:{n}: {line.strip()}"
            for path in sorted((REPO / "hil").rglob("*.py"))
            for n, line in enumerate(path.read_text().splitlines(), 1) if pattern.search(line)]
    assert hits == []


def test_families_are_registered_through_entry_points() -> None:
    installed = families()
    assert {"fbs", "s7-200smart"} <= set(installed)
    for name, plugin in installed.items():
        assert plugin.name == name and plugin.sections and plugin.title


def test_user_errors_are_one_line_and_bugs_show_their_traceback(capsys, monkeypatch):
    """A HilError (here a value the manual does not allow) is one line; an unexpected exception is a bug."""
    from hil.cli import drift
    from hil.cli import main as cli

    assert cli.main(["drift", "code", "99"]) == 4  # pytest's usage error (issue 18: exit codes as pytest's)
    err = capsys.readouterr().err
    assert err.startswith("hil: error: ") and len(err.strip().splitlines()) == 1 and "Traceback" not in err

    def broken(*_args, **_kwargs):
        raise ZeroDivisionError("a bug")
    monkeypatch.setattr(drift, "drift_code", broken)
    assert cli.main(["drift", "code", "1"]) == 3
    err = capsys.readouterr().err
    assert "Traceback" in err and "ZeroDivisionError: a bug" in err and "internal error" in err


def test_a_measurement_is_unset_until_measured():
    from hil.core.measurement import Measurement, Outcome
    declared = Measurement("drift_residual", unit="s/day", low=-0.088, high=0.088)
    assert declared.outcome is Outcome.UNSET and not declared.passed
    assert ("hil.measure.drift_residual.outcome", "UNSET") in declared.properties()
    assert "not measured" in declared.describe()
    assert declared.measured(0.05).outcome is Outcome.PASS
    assert declared.measured(0.2).outcome is Outcome.FAIL
    assert declared.measured(float("nan")).outcome is Outcome.FAIL
    assert f"{declared.measured(0.0).outcome}" == "PASS"  # as it appears in JUnit and HTML


def test_no_private_imports_across_modules():
    """Modules talk through public names: no pytest internals (_pytest), no other module's _private names."""
    import ast
    found = []
    for path in sorted((REPO / "hil").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                if node.module.split(".")[0] == "_pytest":
                    found.append(f"{path.relative_to(REPO)}:{node.lineno} imports {node.module}")
                if node.module.startswith("hil"):
                    found += [f"{path.relative_to(REPO)}:{node.lineno} imports {node.module}.{alias.name}"
                              for alias in node.names if alias.name.startswith("_") and alias.name != "__version__"]
            elif isinstance(node, ast.Import):
                found += [f"{path.relative_to(REPO)}:{node.lineno} imports {alias.name}"
                          for alias in node.names if alias.name.split(".")[0] == "_pytest"]
    assert found == []


def test_no_compiled_kernel_or_build_script():
    """One implementation of each model: no C copy, no extension to build."""
    assert not list((REPO / "hil").rglob("*.c")) and not (REPO / "setup.py").exists()


def _file_cycles(package: str) -> list[list[str]]:
    """The import circles among the modules directly inside ``package`` (each file's own imports, lazy ones and
    TYPE_CHECKING ones too): the strongly connected groups of more than one module, or a module importing itself."""
    import grimp

    graph = grimp.build_graph(package.split(".")[0])
    depth = package.count(".") + 1
    modules = sorted(m for m in graph.modules if m.startswith(package + ".") and m.count(".") == depth)
    imports = {m: sorted(graph.find_modules_directly_imported_by(m) & set(modules)) for m in modules}
    # Tarjan's strongly connected components, iteratively enough for a package's few dozen files
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(module: str) -> None:
        index[module] = low[module] = len(index)
        stack.append(module)
        for other in imports[module]:
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            group = []
            while True:
                top = stack.pop()
                group.append(top)
                if top == module:
                    break
            if len(group) > 1 or module in imports[module]:
                found.append(sorted(group))

    for module in modules:
        if module not in index:
            visit(module)
    return found


def _packages() -> list[str]:
    """Every package of hil (the suites shipped as data are not one)."""
    return ["hil"] + [m.name for m in pkgutil.walk_packages(hil.__path__, "hil.") if m.ispkg and "_data" not in m.name]


@pytest.mark.parametrize("package", _packages())
def test_no_file_level_import_circle_inside_packages(package: str) -> None:
    """Issue 41: inside a package no two files import each other, even through others — a shared piece lives in
    a module of its own below both (an import deferred into a function would only hide the circle)."""
    assert _file_cycles(package) == []
