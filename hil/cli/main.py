"""The ``hil`` command: run the suites, serve the emulator, probe a PLC, work its clock.

A table of commands, as pip's: each lives in its own module, which adds its sub-parser and binds its function
(``set_defaults(func=…)``); this module parses and calls it, and says every error in the one form.  Only the
chosen command's module is imported — the others (pytest, the emulator, SQLAlchemy) would make ``hil --help``
take 0.9 s instead of 0.2 s — so the table keeps each command's one-line summary for the list of commands."""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
import traceback
from dataclasses import dataclass

from rich.console import Console
from rich.text import Text

from hil import __version__
from hil.cli.exits import EXIT_FAILED, EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE
from hil.cli.parser import HilParser, refuse_unknown
from hil.core.errors import ERROR_PREFIX, HilError, InvalidValue, error_line

__all__ = ["COMMANDS", "EXIT_FAILED", "EXIT_INTERNAL", "EXIT_INTERRUPTED", "EXIT_OK", "EXIT_USAGE", "build_parser",
           "main", "one_line"]

EXAMPLES = """examples:
  hil run                                   suites on the in-process emulator, JUnit in reports/junit.xml
  hil run --target emulator+fatek-serial    the same over the FATEK protocol on a pseudo-terminal
  hil run --bench my-bench.toml -- -k rtc   a real bench, RTC suites only (pytest args after --)
  hil run --bench s7-200smart -- s7smart    a bundled profile and suite by short name (hil list shows them)
  hil emulate --fatek-tcp 127.0.0.1:5000    serve the emulator for external clients
  hil probe fatek+serial:///dev/ttyUSB0     status and key registers of a PLC
  hil init fatek+tcp://192.168.1.5:500      a bench profile and a first test, from what the PLC says
  hil rtc read fatek+tcp://192.168.1.5:500  the PLC's clock against host time
  hil drift code 3.38                       the D4054 code for a clock 3.38 s/day fast
"""


@dataclass(frozen=True)
class Command:
    """One ``hil`` command: where it lives and what ``hil --help`` says of it."""
    module: str  # has add_parser(sub, summary): its sub-parser, bound to its function with set_defaults(func=…)
    summary: str
    listing: bool = False  # only shows what is there: a reader that leaves early (| head) has what it wanted
    default_action: str = ""  # the action ``hil COMMAND`` alone (or with only options) means


COMMANDS: dict[str, Command] = {
    "run": Command("hil.cli.run", "run the suites against a bench (default: the emulator)"),
    "emulate": Command("hil.cli.emulate", "serve the emulator on TCP ports and/or pseudo-terminals"),
    "probe": Command("hil.cli.probe", "show a PLC's status and key registers"),
    "list": Command("hil.cli.listing", "the bundled bench profiles and suites, by the short names --bench and hil "
                                       "run take", listing=True),
    "rtc": Command("hil.cli.rtc", "read, set or sync a PLC's real-time clock"),
    "drift": Command("hil.cli.drift", "D4054 rate codes, and measuring a PLC clock's drift"),
    "spec": Command("hil.cli.spec", "the requirement matrix: each manual statement, its tests or why none",
                    listing=True),
    "init": Command("hil.cli.init", "write a bench profile and a first test for a PLC, from what it reads there"),
    "restore": Command("hil.cli.restore", "put back what a run that died left changed on a PLC (its journal)"),
    "history": Command("hil.cli.history", "the runs recorded so far: list, compare, trend, yield, flaky, export",
                       listing=True, default_action="list"),
}


def build_parser(only: str | None = None) -> HilParser:
    """The parser of every command (``only``: that command's in full, the others by name and summary alone)."""
    parser = HilParser(prog="hil", description="Hardware-in-the-loop tests for FATEK FBs PLCs.", epilog=EXAMPLES)
    parser.add_argument("--version", action="version", version=f"hil {__version__}")
    parser.add_argument("--debug", action="store_true", default=False, help="show the traceback of an error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=HilParser)
    for name, command in COMMANDS.items():
        if only in (None, name):
            importlib.import_module(command.module).add_parser(sub, command.summary)
        else:  # listed, never parsed: its module stays unloaded
            sub.add_parser(name, help=command.summary)
    return parser


def _command_at(argv: list[str]) -> int | None:
    """Where the command's name is: the first word that is not an option (hil's own options take no value)."""
    return next((n for n, arg in enumerate(argv) if not arg.startswith("-")), None)


def _with_default_action(argv: list[str]) -> list[str]:
    """``hil history`` alone (or with only options) lists the runs, as ``hil history list`` does."""
    at = _command_at(argv)
    command = COMMANDS.get(argv[at]) if at is not None else None
    if at is None or command is None or not command.default_action:
        return argv
    rest = argv[at + 1:]
    if not rest or (rest[0].startswith("-") and rest[0] not in ("-h", "--help")):
        return [*argv[:at + 1], command.default_action, *rest]
    return argv


def _parse(argv: list[str]) -> argparse.Namespace:
    """The arguments, or exit 4 with the usage and one error line (a typo answered with what it likely meant)."""
    at = _command_at(argv)
    parser = build_parser(only=argv[at] if at is not None else "")  # "": none (hil --help, hil --version)
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        refuse_unknown(parser, argv, unknown)
    return args


def _refuse_empty_urls(args: argparse.Namespace) -> None:
    """A URL the command line gives empty is refused: it must not quietly mean the profile's."""
    for name, what in (("url", "the target URL"), ("target", "--target")):
        value = getattr(args, name, None)
        if value is not None and not value.strip():
            raise InvalidValue(f"{what} is empty — give a target URL (e.g. emulator+fatek-tcp, fatek+tcp://HOST:500), "
                               f"or leave it out to use the bench profile's target")


class _Console(Console):
    """rich's Console, but a closed pipe ends the command as :func:`_reader_left` says, not with rich's exit 1."""

    def on_broken_pipe(self) -> None:
        raise BrokenPipeError


def _reader_left(command: Command) -> int:
    """The reader of our output left (``| head``): nothing more to say to it.  A listing ends with 0 (1 would say
    "tests failed"); any other command was cut short before it could say how it ended — interrupted, never 0."""
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return EXIT_OK if command.listing else EXIT_INTERRUPTED


def say_error(line: str) -> None:
    """An error line on stderr: one line whatever the terminal's width, its prefix in bold red on a terminal."""
    text = Text(line)
    if line.startswith(ERROR_PREFIX):
        text.stylize("bold red", 0, len(ERROR_PREFIX))
    Console(stderr=True, soft_wrap=True).print(text, highlight=False)


def main(argv: list[str] | None = None) -> int:
    argv = _with_default_action(sys.argv[1:] if argv is None else list(argv))
    args = _parse(argv)
    if not args.debug:
        # pymodbus logs its own retries and timeouts ("No response received after 0 retries…") to stderr; the
        # command's one-line error says what failed and what to check.  --debug shows them.
        logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    console = _Console(stderr=False)
    try:
        _refuse_empty_urls(args)
        return int(args.func(args, console))
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        return _reader_left(COMMANDS[args.command])
    except (HilError, OSError) as exc:
        # what the user can act on (a bad profile, an unreachable PLC, a missing port): one line
        if args.debug:
            traceback.print_exc()
        say_error(error_line(one_line(exc)))
        return EXIT_USAGE
    except Exception:  # noqa: BLE001 - anything else is a bug in hil: the traceback, to report
        traceback.print_exc()
        say_error(error_line(f"internal error (a bug in hil {__version__})",
                             "please report it with the traceback above"))
        return EXIT_INTERNAL


def one_line(exc: BaseException) -> str:
    """The error as one line: what failed and what to do (hil's messages say both)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, PermissionError) and exc.filename:
        return f"cannot open {exc.filename}: permission denied — check its owner and mode (serial ports: add " \
               f"your user to the dialout group)"
    if isinstance(exc, FileNotFoundError) and exc.filename:
        return f"{exc.filename}: no such file — check the path"
    return text


if __name__ == "__main__":
    sys.exit(main())
