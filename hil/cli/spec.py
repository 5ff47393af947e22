"""``hil spec``: the requirement matrix — every statement of the catalogue, the suite tests that name it, or why none.

The tests come from the suites' own ``spec(...)`` markers: pytest collects the suites (nothing runs, no bench is
opened) and each collected test's IDs are read.  Exit status 1 when a statement has neither a test nor a reason,
or says no test checks it while a test names it; a test naming an ID the catalogue does not hold is a collection
error (status 4, pytest's usage error, with the test and the ID).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from rich.console import Console
from rich.markup import escape

from hil.cli.parser import Subparsers
from hil.core.errors import error_line
from hil.core.paths import project_dir
from hil.plugin import requirements
from hil.plugin.requirements import REQUIREMENTS_FILE, Requirement, item_ids, load


@dataclass
class Matrix:
    requirements: dict[str, Requirement]
    tests: dict[str, list[str]] = field(default_factory=dict)  # requirement ID → test node IDs
    unmarked: list[str] = field(default_factory=list)  # collected tests that name no requirement

    def missing(self) -> list[Requirement]:
        """Statements with neither a test nor a reason."""
        return [r for r in self.requirements.values() if not r.untested and not self.tests.get(r.id)]

    def contradicted(self) -> list[Requirement]:
        """Statements whose reason says no test can or should check them, while a test names them."""
        return [r for r in self.requirements.values()
                if r.untested and r.untested_kind != "pending" and self.tests.get(r.id)]

    def stale(self) -> list[Requirement]:
        """Statements still marked pending that a test now names (the catalogue's note is out of date)."""
        return [r for r in self.requirements.values() if r.untested_kind == "pending" and self.tests.get(r.id)]

    @property
    def ok(self) -> bool:
        return not self.missing() and not self.contradicted()


class _Collector:
    def __init__(self) -> None:
        self.by_test: dict[str, tuple[str, ...]] = {}

    @pytest.hookimpl(trylast=True)
    def pytest_collection_modifyitems(self, items: list[pytest.Item]) -> None:
        self.by_test = {item.nodeid: item_ids(item) for item in items}


def collect(suites: Path) -> tuple[int, dict[str, tuple[str, ...]], str]:
    """Collect ``suites`` without the bench plugin: (pytest's exit code, test → IDs, pytest's output)."""
    collector = _Collector()
    args = ["--collect-only", "-q", "-p", "no:cacheprovider", "-p", "no:hil", "-p", "no:hil-report",
            "-W", "ignore::pytest.PytestUnknownMarkWarning", str(suites)]
    out = io.StringIO()
    path = list(sys.path)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
            # the spec() marker's plugin as the module this process already imported (``-p`` would ask pytest
            # to rewrite it, and warn that it is already imported)
            code = pytest.main(args, plugins=[collector, requirements])
    finally:
        # in process (a test calling main()), the suites' modules ("conftest", "test_rtc" …) must not stay
        # imported under those names for a later pytest run of other files in the same process
        root = suites.resolve()
        for name, module in list(sys.modules.items()):
            file = getattr(module, "__file__", None)
            if file and Path(file).resolve().is_relative_to(root):
                del sys.modules[name]
        sys.path[:] = path
    return int(code), collector.by_test, out.getvalue()


def build(suites: Path, catalogue: Path = REQUIREMENTS_FILE) -> tuple[int, Matrix, str]:
    code, by_test, output = collect(suites)
    matrix = Matrix(load(catalogue))
    matrix.unmarked = [test for test, ids in by_test.items() if not ids]
    for test, ids in by_test.items():
        for rid in ids:
            matrix.tests.setdefault(rid, []).append(test)
    return code, matrix, output


def spec(suites: Path, console: Console, *, verbose: bool = False) -> int:
    code, matrix, output = build(suites)
    if code not in (0, 5):  # 5: nothing collected (an empty suites directory still lists the catalogue)
        console.print(escape(output.rstrip()), highlight=False)
        _say(console, error_line(f"collecting {suites} failed (pytest exit {code})", "see pytest's output above"))
        return code
    for req in matrix.requirements.values():
        _print_requirement(console, req, matrix.tests.get(req.id, []), verbose)
    _print_totals(console, matrix, suites, verbose)
    _print_problems(console, matrix)
    return 0 if matrix.ok else 1


def _say(console: Console, text: str) -> None:
    console.print(escape(text), highlight=False, soft_wrap=True)


def _status(req: Requirement, tests: list[str]) -> str:
    """How the statement is covered: its tests, the reason it has none, or neither."""
    if tests:
        return f"{len(tests)} test{'s' if len(tests) != 1 else ''}"
    if req.untested:
        return f"no test: {req.untested_kind} — {req.untested_reason}"
    return "MISSING: neither a test nor a reason"


def _print_requirement(console: Console, req: Requirement, tests: list[str], verbose: bool) -> None:
    """One statement's line (with ``verbose``, its text and its tests below it) and its gap, if tested."""
    tag = " [our choice]" if req.choice else ""
    _say(console, f"{req.id:<14} {req.manual}{tag}: {_status(req, tests)}")
    if verbose:
        _say(console, f"    {req.statement}")
        for test in tests:
            _say(console, f"    - {test}")
    if req.gap and tests:
        _say(console, f"    gap: {req.gap}")


def _print_totals(console: Console, matrix: Matrix, suites: Path, verbose: bool) -> None:
    requirements = matrix.requirements.values()
    tested = sum(1 for r in requirements if matrix.tests.get(r.id))
    untested = sum(1 for r in requirements if r.untested and not matrix.tests.get(r.id))
    marks = sum(len(t) for t in matrix.tests.values())
    _say(console, f"{len(matrix.requirements)} requirements: {tested} with tests, {untested} with a reason, "
                  f"{len(matrix.missing())} with neither ({marks} test marks in {suites})")
    if matrix.unmarked:
        _say(console, f"{len(matrix.unmarked)} collected tests name no requirement"
                      + (": " + ", ".join(matrix.unmarked) if verbose else " (-v lists them)"))


def _print_problems(console: Console, matrix: Matrix) -> None:
    """What makes the matrix fail (exit 1), one error line each, after a note on what is only out of date."""
    for req in matrix.stale():
        _say(console, f"note: {req.id} is still 'pending' in the catalogue but tests name it: "
                      f"{', '.join(matrix.tests[req.id])}")
    for req in matrix.contradicted():
        _say(console, error_line(f"{req.id} says '{req.untested_kind}' (no test) but tests name it: "
                                 f"{', '.join(matrix.tests[req.id])}",
                                 f"drop its reason from {REQUIREMENTS_FILE.name}, or the tests' spec() marks"))
    for req in matrix.missing():
        _say(console, error_line(f"{req.id} has neither a test nor a reason",
                                 f'mark a test with spec("{req.id}"), or give a reason in {REQUIREMENTS_FILE.name}'))


# -- the command line -----------------------------------------------------------------------------------------------
def add_parser(sub: Subparsers, summary: str) -> None:
    parser = sub.add_parser("spec", help=summary,
                            epilog="examples:\n  hil spec\n  hil spec -v            (statements and test names)\n"
                                   "Exit 1 when a statement has neither a test nor a reason; 4 when a test names an ID "
                                   "not in hil/requirements.toml.\n")
    parser.add_argument("--suites", metavar="DIR", help="the suites to read the spec() markers of (default: suites/ "
                                                        "here, else the bundled suites)")
    parser.add_argument("-v", "--verbose", action="store_true", help="each statement and the tests that name it")
    parser.set_defaults(func=command)


def command(args: argparse.Namespace, console: Console) -> int:
    return spec(Path(args.suites) if args.suites else project_dir("suites"), console, verbose=args.verbose)
