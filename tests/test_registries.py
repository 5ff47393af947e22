"""Families and wires are registered, not listed: the generic layers' code names no family, protocol of a family,
or register (comments and docstrings aside: those may give examples), and what the families register is whole."""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

from hil.bench.family import default_family, families
from hil.core.registry import PROTOCOLS, SCHEMES, WIRES, Registry
from tests.conftest import REPO

GENERIC = ("hil/core", "hil/io", "hil/sim", "hil/bench", "hil/plugin")
#: an element of a PLC's memory: R4128, D4054, M1000, VB100 (a letter or two, then its number; FC16 is a Modbus
#: function code)
REGISTER = r"\b(?!FC)[A-Z]{1,2}[0-9]{2,5}\b"


def family_words() -> re.Pattern[str]:
    """Each installed family's name and the protocols only families bring (Modbus is hil.io's own wire), in any
    case; the words of a family's title and a register as they are written ("SMART", not a smart plug)."""
    names = {w for plugin in families().values() for w in (plugin.name, plugin.name.split("-")[0])}
    names |= {name for name in PROTOCOLS if name != "modbus"}
    titles = {w for plugin in families().values() for w in plugin.title.split()}

    def either(words: set[str]) -> str:
        return "|".join(sorted(map(re.escape, words), key=len, reverse=True))
    return re.compile(f"(?i:{either(names)})|{either(titles)}|{REGISTER}")


def code_strings(source: str) -> list[tuple[int, str]]:
    """(line, text) of every name and string token outside comments and docstrings."""
    docstrings = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(getattr(first.value, "value", None), str):
                docstrings.update(range(first.lineno, (first.end_lineno or first.lineno) + 1))
    return [(tok.start[0], tok.string) for tok in tokenize.generate_tokens(io.StringIO(source).readline)
            if tok.type in (tokenize.NAME, tokenize.STRING, getattr(tokenize, "FSTRING_MIDDLE", tokenize.STRING))
            and not (tok.type == tokenize.STRING and tok.start[0] in docstrings)]


def family_names_in(root: Path) -> list[str]:
    pattern = family_words()
    return [f"{path.relative_to(root)}:{line}: {text[:90]}"
            for folder in GENERIC for path in sorted((root / folder).rglob("*.py"))
            for line, text in code_strings(path.read_text())
            if pattern.search(text)]


def test_the_generic_layers_name_no_family_or_register() -> None:
    """User-facing words (examples in help texts, the default family, the lab's default protocol) come from the
    registries; a family's names live in its own package."""
    assert family_names_in(REPO) == []


def test_every_scheme_speaks_a_registered_protocol_and_every_wire_has_its_target() -> None:
    for name, scheme in SCHEMES.items():
        assert scheme.protocol in PROTOCOLS or scheme.protocol == "local", name
        assert not scheme.default_port or scheme.network, name
    for name, wire in WIRES.items():
        assert SCHEMES[f"emulator+{name}"].in_process and wire.kind in ("tcp", "udp", "pty")
        assert any(name in plugin.wires for plugin in families().values()), f"no family serves {name}"
    assert sum(p.lab_default for p in PROTOCOLS.values()) == 1
    assert default_family().name in families()


def test_a_name_registered_twice_differently_is_refused() -> None:
    table: Registry[int] = Registry("thing")
    table.register("a", 1)
    table.register("a", 1)  # two families that speak one wire both register it
    with pytest.raises(ValueError, match="thing 'a' is registered twice"):
        table.register("a", 2)


def local_imports_of_hil(root: Path) -> list[str]:
    """``from hil… import`` / ``import hil…`` inside a function, anywhere in hil/."""
    found = set()
    for path in sorted((root / "hil").rglob("*.py")):
        for fn in ast.walk(ast.parse(path.read_text())):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(fn):
                    if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("hil"):
                        found.add(f"{path.relative_to(root)}:{node.lineno} {node.module}")
                    elif isinstance(node, ast.Import) and any(a.name.startswith("hil") for a in node.names):
                        found.add(f"{path.relative_to(root)}:{node.lineno} {node.names[0].name}")
    return sorted(found)


def test_hil_modules_are_imported_at_the_top() -> None:
    """No import closes a cycle at run time, so a module's imports are at its top, where a reader looks.  The
    command line imports only the chosen command's module, by its name in the command table (``hil --help`` would
    otherwise import the emulator and pytest: 0.9 s instead of 0.1 s).  The optional dependencies (snap7,
    matplotlib) are deferred inside the hil modules that use them."""
    found = local_imports_of_hil(REPO)
    assert found == [], found


def test_each_emulator_wire_has_one_name_and_a_flag_of_that_name(capsys: pytest.CaptureFixture[str]) -> None:
    """``emulator+fatek-serial``, ``hil emulate --fatek-serial``, its endpoint line ``fatek-serial PATH``; the
    earlier ``--fatek-pty`` is still accepted, not shown."""
    from hil.cli.main import build_parser
    parser = build_parser()
    for name, wire in WIRES.items():
        given = [wire.option] if wire.kind == "pty" else [wire.option, "127.0.0.1:0"]
        assert getattr(parser.parse_args(["emulate", *given]), f"wire:{name}")
        for alias in wire.aliases:
            assert getattr(parser.parse_args(["emulate", f"--{alias}"]), f"wire:{name}")
    with pytest.raises(SystemExit):
        parser.parse_args(["emulate", "--help"])
    shown = capsys.readouterr().out
    assert all(wire.option in shown for wire in WIRES.values())
    assert not any(f"--{alias}" in shown for wire in WIRES.values() for alias in wire.aliases)
