"""The code's shape, checked in CI (issue 41): ruff's rules over the repository and mypy over the whole package
(their configuration and the reasons for it are in pyproject.toml), and the size bounds a maintainer can hold in
their head — no function above cyclomatic complexity 20 (radon's measure), no class above 300 lines."""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

from radon.complexity import cc_visit
from radon.visitors import Class, Function

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "hil"
#: the bounds (issue 41's acceptance)
MOST_COMPLEX = 20
LONGEST_CLASS = 300


def _sources() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "_data" not in p.parts)


def test_ruff_finds_nothing() -> None:
    # the whole repository: the package, its tests, the suites, the benchmarks and scripts (pyproject.toml says
    # which rules the tests and suites leave out, and why)
    done = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache"], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr


def test_mypy_finds_nothing(tmp_path) -> None:
    done = subprocess.run([sys.executable, "-m", "mypy", "--cache-dir", str(tmp_path)], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr


def _functions(blocks: list) -> Iterator[Function]:
    for block in blocks:
        if isinstance(block, Class):
            yield from _functions(block.methods)
            yield from _functions(block.inner_classes)
        else:
            yield block
            yield from _functions(block.closures)


def test_no_function_is_more_complex_than_20() -> None:
    # (radon lists a method both on its own and in its class's methods: a set of the lines says each once)
    over = sorted({f"{path.relative_to(ROOT)}:{f.lineno} {f.fullname} {f.complexity}"
                   for path in _sources() for f in _functions(cc_visit(path.read_text(encoding="utf-8")))
                   if f.complexity > MOST_COMPLEX})
    assert not over, f"above cyclomatic complexity {MOST_COMPLEX} (split it into named steps):\n" + "\n".join(over)


def test_no_class_is_longer_than_300_lines() -> None:
    over = [f"{path.relative_to(ROOT)}:{node.lineno} {node.name} {node.end_lineno - node.lineno + 1} lines"
            for path in _sources() for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
            if isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > LONGEST_CLASS]
    assert not over, f"classes longer than {LONGEST_CLASS} lines (one concept each):\n" + "\n".join(over)
