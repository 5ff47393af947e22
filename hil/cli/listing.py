"""``hil list``: the bench profiles and suites reachable by short name (``--bench s7-200smart``, ``hil run -- rtc``),
from a checkout or an installed wheel alike."""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

from rich.console import Console
from rich.markup import escape

from hil.bench.profile import load_profile
from hil.cli.parser import Subparsers
from hil.core.errors import HilError
from hil.core.paths import bundled_benches, bundled_suites


def _summary(path: Path) -> str:
    """A suite's purpose: the first line of its module docstring; a directory: the suites in it."""
    if path.is_dir():
        return "the suites " + ", ".join(p.stem.removeprefix("test_") for p in sorted(path.glob("test_*.py")))
    try:
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    except (OSError, SyntaxError, UnicodeDecodeError):
        return ""
    return doc.strip().splitlines()[0].rstrip(".") if doc.strip() else ""


def list_all(console: Console) -> int:
    """One line per profile and per suite, plain (a pipe or a CI log reads it as a terminal does)."""
    benches, suites = bundled_benches(), bundled_suites()
    out = ["bench profiles (hil run --bench NAME; a file path works too):"]
    for name, path in benches.items():
        try:
            profile = load_profile(path)
            what = f"{profile.family:<12} {profile.target}"
        except HilError as exc:  # an example that needs editing (or a labgrid place) still shows, with why
            what = " ".join(str(exc).split())[:100]
        out.append(f"  {name:<20} {what}   ({path})")
    out.append("suites (hil run -- NAME …; pytest's -k, -x … after them):")
    for name, path in suites.items():
        out.append(f"  {name:<20} {_summary(path)}   ({path})")
    for line in out:
        console.print(escape(line), highlight=False, soft_wrap=True)
    return 0


# -- the command line -----------------------------------------------------------------------------------------------
def add_parser(sub: Subparsers, summary: str) -> None:
    listing = sub.add_parser("list", help=summary, epilog="examples:\n  hil list\n  hil run --bench s7-200smart\n"
                                                          "  hil run -- rtc rtc_adjust\n")
    listing.set_defaults(func=command)


def command(args: argparse.Namespace, console: Console) -> int:
    return list_all(console)
