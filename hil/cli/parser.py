"""hil's argparse parser: a usage error is one line in hil's error form (exit 4, pytest's usage error), said by
the (sub-)command the user typed, with the command or option they most likely meant."""

from __future__ import annotations

import argparse
import difflib
import re
import sys
from typing import Any, NoReturn

from hil.cli.exits import EXIT_USAGE
from hil.cli.reference import Subparsers, commands, options
from hil.core.errors import error_line
from hil.core.redact import hide_passwords

__all__ = ["HilParser", "Subparsers", "did_you_mean", "refuse_unknown", "typed_command"]


class HilParser(argparse.ArgumentParser):
    """argparse with hil's error line and pytest's exit code for a usage error (4, not argparse's 2 = pytest's
    "interrupted"), examples kept as written, and ``--debug`` accepted after any sub-command."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
        super().__init__(*args, **kwargs)
        if self.prog != "hil":  # a sub-command's parser
            # SUPPRESS: absent after the sub-command, the top-level value stands
            self.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                              help="show the traceback of an error")

    def error(self, message: str) -> NoReturn:
        self.fail(message, did_you_mean(message) or self.see_help())

    def fail(self, what: str, next_step: str) -> NoReturn:
        """The usage of this command (what it takes), then the one error line; exit 4."""
        self.print_usage(sys.stderr)
        # (it may echo a store's URL: its password hidden)
        self.exit(EXIT_USAGE, error_line(hide_passwords(what), hide_passwords(next_step)) + "\n")

    def see_help(self) -> str:
        return f"see {self.prog} --help"


def did_you_mean(message: str) -> str:
    """For argparse's "invalid choice: 'rnu' (choose from 'run', …)", the choice the user most likely meant."""
    found = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
    if not found:
        return ""
    close = difflib.get_close_matches(found.group(1), re.findall(r"'([^']*)'", found.group(2)), n=1)
    return f"did you mean '{close[0]}'?" if close else ""


def typed_command(parser: argparse.ArgumentParser, argv: list[str]) -> HilParser:
    """The parser of the (sub-)command ``argv`` names — ``hil history trend`` — whose usage an error shows."""
    words = [a for a in argv if not a.startswith("-")]
    found = parser
    for command in commands(parser):
        path = command.prog.split()[1:]
        if path and words[:len(path)] == path:
            found = command.parser
    assert isinstance(found, HilParser)
    return found


def refuse_unknown(parser: argparse.ArgumentParser, argv: list[str], unknown: list[str]) -> NoReturn:
    """Options the command does not know, said by that command's parser: a close option of its own first (a
    typo: ``--bnech`` → ``--bench``), else, for ``hil run``, that pytest's options go after ``--``."""
    own = typed_command(parser, argv)
    known = options(own)
    close = {u: difflib.get_close_matches(u.split("=")[0], known, n=1) for u in unknown if u.startswith("--")}
    meant = {u: c[0] for u, c in close.items() if c}
    if meant:
        own.fail(f"unrecognized arguments: {', '.join(meant)}", _meant(meant))
    if own.prog == "hil run":
        own.fail(f"unrecognized arguments: {' '.join(unknown)}",
                 f"pytest's own options go after '--', e.g. hil run -- {' '.join(_after_run(argv))}")
    own.fail(f"unrecognized arguments: {' '.join(unknown)}", own.see_help())


def _meant(meant: dict[str, str]) -> str:
    if len(meant) == 1:
        return f"did you mean {next(iter(meant.values()))}?"
    return "did you mean " + ", ".join(f"{option} (for {typed})" for typed, option in meant.items()) + "?"


def _after_run(argv: list[str]) -> list[str]:
    rest = argv[argv.index("run") + 1:] if "run" in argv else argv
    return [a for a in rest if a != "--"]
