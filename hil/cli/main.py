"""The ``hil`` command: run the suites, serve the emulator, probe a PLC, work its clock."""

from __future__ import annotations

import argparse
import difflib
import logging
import os
import re
import sys
import traceback
from pathlib import Path

from rich.console import Console
from rich.markup import escape

from hil import __version__
from hil.cli.history_parser import add_parser as add_history
from hil.cli.reference import commands
from hil.core.errors import HilError, InvalidValue
from hil.core.paths import default_bench, project_dir
from hil.core.redact import hide_passwords
from hil.core.registry import WIRES

# Exit codes: pytest's (``pytest.ExitCode``), so a script or CI job reads ``hil run`` and the other commands alike.
EXIT_OK, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_INTERNAL, EXIT_USAGE = 0, 1, 2, 3, 4

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


class _Parser(argparse.ArgumentParser):
    """argparse with pytest's exit code for a usage error (4, not argparse's 2 = pytest's "interrupted"), a hint
    for pytest options given to ``hil run`` before ``--``, and ``--debug`` accepted after any sub-command."""

    def __init__(self, *args, **kwargs) -> None:  # noqa: ANN002, ANN003
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
        super().__init__(*args, **kwargs)
        if self.prog != "hil":  # a sub-command's parser
            # SUPPRESS: absent after the sub-command, the top-level value stands
            self.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                              help="show the traceback of an error")

    def error(self, message: str):
        self.print_usage(sys.stderr)
        # (it may echo a store's URL: its password hidden)
        self.exit(EXIT_USAGE, f"{self.prog}: error: {hide_passwords(message)}{_did_you_mean(message)}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="hil", description="Hardware-in-the-loop tests for FATEK FBs PLCs.", epilog=EXAMPLES)
    parser.add_argument("--version", action="version", version=f"hil {__version__}")
    parser.add_argument("--debug", action="store_true", default=False, help="show the traceback of an error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=_Parser)

    run = sub.add_parser("run", help="run the suites against a bench (default: the emulator)",
                         formatter_class=argparse.RawDescriptionHelpFormatter,
                         description="Run the suites with pytest and leave the evidence in reports/: junit.xml "
                                     "(bench, PLC identity, measurements with limits, wire traces of failures), "
                                     "report.html (one offline file with plots) and traces/.",
                         epilog="examples:\n  hil run\n  hil run --target emulator+modbus-tcp\n"
                                "  hil run --bench fixtures/benches/example-bench.toml --operator \"J. Doe\" "
                                "--station rig-2\n"
                                "  hil run --bench my-bench.toml -- -k smoke -x     (pytest arguments after --)\n"
                                "  hil run --bench my-bench.toml -- --hil-run-slow  (the slow tests on a bench too: "
                                "the closed loop, drift)\n"
                                "  hil run --bench my-bench.toml -- --hil-allow-destructive  (RUN/STOP and outputs)\n"
                                "  hil run -q --trace all | tee run.log           (plain text in a pipe)\n"
                                "  hil run --bench my-bench.toml --lanes 2      (two lanes share a slow line)\n"
                                "  hil run --bench lab-fbs.toml --lg-reserve \"family=fbs rtc=s35390a\"  (a labgrid "
                                "place)\n")
    run.add_argument("--bench", metavar="FILE", action="append",
                     help="bench profile: a file or a bundled profile's name, e.g. s7-200smart (hil list; default "
                          "fixtures/benches/emulator.toml); give it more than once to run "
                          "the benches in parallel (junit-<bench>.xml each, merged into --junitxml)")
    run.add_argument("--target", metavar="URL", help="target URL overriding the profile's")
    lab = run.add_argument_group("a lab of benches (labgrid)")
    lab.add_argument("--lg-place", metavar="NAME",
                     help="run on this labgrid place: reserve it, wait for it (a progress line), acquire it, take the "
                          "target and the fault rig from its resources, release it at the end (also on failure and "
                          "Ctrl-C)")
    lab.add_argument("--lg-reserve", metavar="TAGS",
                     help="run on any labgrid place with these tags, e.g. \"family=fbs rtc=s35390a\"")
    lab.add_argument("--lg-coordinator", metavar="HOST:PORT",
                     help="the labgrid coordinator (default: the profile's [labgrid] coordinator, $LG_COORDINATOR, "
                          "127.0.0.1:20408)")
    lab.add_argument("--lg-wait", metavar="SECONDS", type=float,
                     help="give up when no place is allocated within SECONDS (default: wait as long as it takes)")
    run.add_argument("--junitxml", metavar="PATH", default="reports/junit.xml",
                     help="where the JUnit XML goes (default reports/junit.xml)")
    run.add_argument("--html", metavar="PATH", default="reports/report.html",
                     help="where the HTML report goes (default reports/report.html)")
    run.add_argument("--lanes", metavar="N", type=int, default=None,
                     help="run the suites' lanes at the same time, in N processes sharing the bench (pytest-xdist "
                          "-n N --dist each; hil.plugin.lanes): the RTC suites beside the temperature and PID ones; on port 0 at "
                          "9600 bit/s one fills the line while the other waits for the PLC (docs/performance.md)")
    run.add_argument("--operator", metavar="NAME", help="who runs the tests (default $HIL_OPERATOR or login name)")
    run.add_argument("--station", metavar="NAME", help="test station (default $HIL_STATION or host name)")
    run.add_argument("--trace", choices=("failures", "all", "off"), default=None,
                     help="wire traces to keep: failing tests (default), all, or off")
    run.add_argument("-q", "--quiet", action="count", default=0, help="less output (repeat for even less)")
    run.add_argument("-v", "--verbose", action="count", default=0, help="one line per test")
    run.add_argument("--color", choices=("auto", "yes", "no"), default=None,
                     help="colour the console (default auto: only on a terminal, never with NO_COLOR)")
    run.add_argument("pytest_args", nargs=argparse.REMAINDER,
                     help="after --: pytest arguments; test files or ids, or suites by short name (hil list), "
                          "given there are the only ones run (default: every suite), e.g. hil run -- rtc -k leap")

    emulate = sub.add_parser("emulate", help="serve the emulator on TCP ports and/or pseudo-terminals",
                             formatter_class=argparse.RawDescriptionHelpFormatter,
                             epilog="examples:\n  hil emulate --fatek-tcp 127.0.0.1:5000 --modbus-tcp 127.0.0.1:5020\n"
                                    "  hil emulate --fatek-serial --time-scale 60\n"
                                    "  hil emulate --bench fixtures/benches/emulator.toml --fatek-tcp 0.0.0.0:500\n"
                                    "Prints one line per endpoint, '<kind> <address-or-pty-path>', once it listens; "
                                    "on a terminal a live panel (clock, temperatures, requests) follows. Ctrl-C "
                                    "stops.")
    emulate.add_argument("--no-live", action="store_true", help="no live panel, even on a terminal")
    emulate.add_argument("--bench", metavar="FILE", help="bench profile that configures the emulator")
    for wire in WIRES.values():  # every registered emulator wire: --NAME HOST:PORT, or --NAME for a pty
        if wire.kind == "pty":
            emulate.add_argument(wire.option, action="store_true", dest=f"wire:{wire.name}", help=wire.help)
            for alias in wire.aliases:
                emulate.add_argument(f"--{alias}", action="store_true", dest=f"wire:{wire.name}",
                                     help=argparse.SUPPRESS)
        else:
            emulate.add_argument(wire.option, metavar="HOST:PORT", dest=f"wire:{wire.name}", help=wire.help)
    emulate.add_argument("--line", metavar="'BAUD FRAME'",
                         help="pace the pseudo-terminals' characters at this line rate, e.g. '9600 7E1' (port 0's "
                              "factory setting; default: the profile's [emulator] line, else unpaced)")
    emulate.add_argument("--rig-modbus-tcp", metavar="HOST:PORT",
                         help="also serve a fault rig, a Modbus/TCP relay module: coil FIRST+point = 1 opens the "
                              "point's sensor, FIRST+32+point its heater circuit, FIRST+64+point shorts its SSR "
                              "(profile: [faults.sensor_break|heater_open|ssr_short] kind = \"modbus-coil\", "
                              "first_coil = FIRST, FIRST+32, FIRST+64)")
    emulate.add_argument("--rig-first-coil", type=int, default=0, metavar="FIRST",
                         help="the rig's first coil: temperature point 0's sensor (default 0)")
    emulate.add_argument("--time-scale", type=float, default=1.0, metavar="X",
                         help="virtual seconds per wall second (default 1)")
    emulate.add_argument("--timing", choices=("instant", "bench"),
                         help="'bench': readings, table rewrites and PID steps as late as the manual allows, scans "
                              "of varying length, at seeded phases (default: the profile's [emulator] timing)")
    emulate.add_argument("--seed", type=int, metavar="N",
                         help="the emulator's seed (timing phases, plant noise; default: the profile's [emulator] "
                              "seed); hil emulate prints the one in effect at start")

    probe = sub.add_parser("probe", help="show a PLC's status and key registers",
                           formatter_class=argparse.RawDescriptionHelpFormatter,
                           description="Connect, ask the PLC what it is (FATEK command 53 where the wire has it) "
                                       "and show its state and key registers. Reads only.",
                           epilog="examples:\n  hil probe fatek+tcp://192.168.1.5:500\n"
                                  "  hil probe fatek+serial:///dev/ttyUSB0?baudrate=19200\n"
                                  "  hil probe modbus+tcp://192.168.1.5:502?unit=1\n"
                                  "  hil probe fatek+rfc2217://exporter:3001   (port 0 behind ser2net / labgrid)\n"
                                  "  hil probe --bench fixtures/benches/emulator.toml   (the profile's target, "
                                  "with its temperature points)\n")
    probe.add_argument("url", nargs="?", help="target URL, e.g. fatek+serial:///dev/ttyUSB0 or emulator+modbus-tcp "
                                              "(default: the --bench profile's target, else the emulator, as hil run)")
    probe.add_argument("--bench", metavar="FILE",
                       help="bench profile: its [temperature] section adds the temperature points to the report "
                            "(and configures an emulator… target)")
    sub.add_parser("list", help="the bundled bench profiles and suites, by the short names --bench and hil run take",
                   formatter_class=argparse.RawDescriptionHelpFormatter,
                   epilog="examples:\n  hil list\n  hil run --bench s7-200smart\n  hil run -- rtc rtc_adjust\n")
    _add_clock_commands(sub)
    _add_init_command(sub)
    restore = sub.add_parser("restore", help="put back what a run that died left changed on a PLC (its journal)",
                             formatter_class=argparse.RawDescriptionHelpFormatter,
                             description="Every run journals each value before it first writes it (on disk, "
                                         "fsync'd); a run that dies leaves the journal behind and the next run on "
                                         "that PLC replays it first. This does it by hand, holding the bench lock.",
                             epilog="examples:\n  hil restore --bench my-bench.toml\n"
                                    "  hil restore --show                 (every bench's pending journal)\n"
                                    "  hil restore --show --bench my-bench.toml   (and what a restore would do, "
                                    "read from the PLC)\n"
                                    "  hil restore --show fatek+tcp://192.168.1.5\n")
    restore.add_argument("url", nargs="?", help="target URL (default: the --bench profile's target)")
    restore.add_argument("--bench", metavar="FILE", help="bench profile (its target, timeout and time scale)")
    restore.add_argument("--show", action="store_true",
                         help="list every journal (whose, which bench) and, with --bench, what a restore would do "
                              "with each entry on the PLC as it reads now; write nothing")
    restore.add_argument("--accept-host-clock", action="store_true",
                         help="set the PLC's clock from a journal written during another boot of this host, on the "
                              "host clock as it is now (whether it was stepped since cannot be checked)")
    add_history(sub)
    return parser


def _add_clock_commands(sub: argparse._SubParsersAction) -> None:
    """``hil rtc read|set|sync`` and ``hil drift code|decode|measure`` (see hil/commands/rtc.py)."""
    raw = argparse.RawDescriptionHelpFormatter
    url_help = ("target URL, e.g. fatek+tcp://192.168.1.5:500, fatek+serial:///dev/ttyUSB0 or emulator+fatek-tcp "
                "(default: the --bench profile's target, else the emulator)")
    bench_help = "bench profile for an emulator… target (default fixtures/benches/emulator.toml: an S-35390A RTC)"

    rtc = sub.add_parser("rtc", help="read, set or sync a PLC's real-time clock", formatter_class=raw,
                         description="The PLC's real-time clock (R4128–R4135, M1952–M1955, D4053/D4054). Writes go "
                                     "straight to the PLC: no bench profile guards them.",
                         epilog="examples:\n  hil rtc read fatek+tcp://192.168.1.5:500\n"
                                "  hil rtc set fatek+serial:///dev/ttyUSB0 \"2024-02-29 12:00:00\"\n"
                                "  hil rtc sync emulator+modbus-tcp\n")
    rtc_sub = rtc.add_subparsers(dest="rtc_command", metavar="ACTION", required=True)
    read = rtc_sub.add_parser("read", help="the time, chip, flags and rate code, and the difference from host time",
                              formatter_class=raw,
                              epilog="examples:\n  hil rtc read fatek+tcp://192.168.1.5:500\n"
                                     "  hil rtc read emulator+modbus-tcp    (D4053/D4054 are not on the Modbus map)\n")
    set_ = rtc_sub.add_parser("set", help="set the clock (M1952 procedure); exit 1 if the PLC refuses (M1955 = 1)",
                              formatter_class=raw,
                              epilog="examples:\n  hil rtc set fatek+tcp://192.168.1.5:500 \"2024-02-29 12:00:00\"\n"
                                     "  hil rtc set emulator 2024-02-29T12:00\n"
                                     "An invalid date (2023-02-29) is sent as is, so you see whether the PLC takes "
                                     "it.\n")
    sync = rtc_sub.add_parser("sync", help="set the clock to host time, on a whole second", formatter_class=raw,
                              epilog="example:\n  hil rtc sync fatek+serial:///dev/ttyUSB0\n")
    for p in (read, set_, sync):
        p.add_argument("url", metavar="URL", nargs="?", help=url_help)
    set_.add_argument("time", metavar="TIME", help="YYYY-MM-DD HH:MM:SS (ISO; 'T' or space; seconds optional)")
    for p in (read, set_, sync):
        p.add_argument("--bench", metavar="FILE", help=bench_help)

    drift = sub.add_parser("drift", help="D4054 rate codes, and measuring a PLC clock's drift", formatter_class=raw,
                           description="S-35390A clock-rate compensation (D4054). Positive rates mean the PLC clock "
                                       "runs fast.",
                           epilog="examples:\n  hil drift code 3.38\n  hil drift decode 56E5H\n"
                                  "  hil drift measure fatek+tcp://192.168.1.5:500 --duration 3600\n")
    drift_sub = drift.add_subparsers(dest="drift_command", metavar="ACTION", required=True)
    code = drift_sub.add_parser("code", help="the manual's D4054 code for a clock error in s/day", formatter_class=raw,
                                epilog="examples:\n  hil drift code 3.38     -> 56E5H\n"
                                       "  hil drift code -5.62    -> 5603H (a clock 5.62 s/day slow)\n")
    code.add_argument("rate", metavar="RATE", help="s/day the PLC clock runs fast (negative: slow), "
                                                  "-16.88 … +16.61")
    decode = drift_sub.add_parser("decode", help="what a D4054 code does: mode, steps, s/day, ppm",
                                  formatter_class=raw,
                                  epilog="examples:\n  hil drift decode 56E5\n  hil drift decode 0x5603\n"
                                         "  hil drift decode 56E5H\n")
    decode.add_argument("code", metavar="CODE", help="hex: 56E5, 56E5H or 0x56E5")
    measure = drift_sub.add_parser("measure", help="measure the clock's error in s/day against host time",
                                   formatter_class=raw,
                                   epilog="examples:\n  hil drift measure fatek+tcp://192.168.1.5:500 --duration 3600\n"
                                          "  hil drift measure emulator --duration 86400   (virtual time: instant)\n"
                                          "  hil drift measure fatek+serial:///dev/ttyUSB0 --duration 86400 --apply\n"
                                          "Longer is finer: the resolution is one polling bracket (tens of ms) over "
                                          "the duration, about ±0.03 s/day over a day. Without --apply D4054 is left "
                                          "as it is.\n")
    measure.add_argument("url", metavar="URL", nargs="?", help=url_help)
    measure.add_argument("--duration", type=float, required=True, metavar="SECONDS",
                         help="bench seconds to measure over (more than 5)")
    measure.add_argument("--apply", action="store_true",
                         help="then write the compensating code to D4054 (S-35390A; not over the default Modbus map)")
    measure.add_argument("--bench", metavar="FILE", help=bench_help)

    spec = sub.add_parser("spec", help="the requirement matrix: each manual statement, its tests or why none",
                          formatter_class=raw,
                          epilog="examples:\n  hil spec\n  hil spec -v            (statements and test names)\n"
                                 "Exit 1 when a statement has neither a test nor a reason; 4 when a test names an ID "
                                 "not in hil/requirements.toml.\n")
    spec.add_argument("--suites", metavar="DIR", help="the suites to read the spec() markers of (default: suites/ "
                                                      "here, else the bundled suites)")
    spec.add_argument("-v", "--verbose", action="store_true", help="each statement and the tests that name it")


def _add_init_command(sub: argparse._SubParsersAction) -> None:
    init = sub.add_parser("init", help="write a bench profile and a first test for a PLC, from what it reads there",
                          formatter_class=argparse.RawDescriptionHelpFormatter,
                          description="Read-only: the PLC's status, identity, RTC chip (D4053) and, with "
                                      "--temperature-table, its temperature table; writes DIR/bench.toml and "
                                      "DIR/tests/test_first.py, with commented placeholders for the rest.",
                          epilog="examples:\n  hil init fatek+tcp://192.168.1.5:500 --temperature-table R3000\n"
                                 "  hil init fatek+serial:///dev/ttyUSB0 --dir my-bench --name \"line 3\"\n")
    init.add_argument("url", help="target URL of the PLC (fatek+tcp://HOST:500, fatek+serial:///dev/ttyUSB0, "
                                  "modbus+tcp://HOST:502?unit=1 …)")
    init.add_argument("--dir", metavar="DIR", default=".", help="where to write (default: here)")
    init.add_argument("--name", help="the bench's name, which keys its run history (default: the directory's name)")
    init.add_argument("--scratch", metavar="RANGE", action="append", default=[],
                      help="registers or bits nobody else uses on this PLC (e.g. R1000-R1099; again for more): "
                           "[bench] scratch and [safety] writable, for the smoke suite's round trips")
    init.add_argument("--temperature-table", metavar="ADDRESS",
                      help="where the ladder keeps the temperature table (SR, e.g. R3000): read and filled in")
    init.add_argument("--time-scale", metavar="N", type=float, default=1.0,
                      help="[bench] time_scale: 1 for a PLC; N for a hil emulate --time-scale N (default 1)")
    init.add_argument("--force", action="store_true", help="overwrite bench.toml and tests/test_first.py")


#: commands that only show what is there: a reader that left early (``| head``) has what it wanted
LISTINGS = ("list", "spec", "history")


def _reader_left(command: str) -> int:
    """The reader of our output left (``| head``): nothing more to say to it.  A listing ends with 0 (1 would say
    "tests failed"); any other command was cut short before it could say how it ended — interrupted, never 0."""
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return EXIT_OK if command in LISTINGS else EXIT_INTERRUPTED


class _Console(Console):
    """rich's Console, but a closed pipe ends the command as :func:`_reader_left` says, not with rich's exit 1."""

    def on_broken_pipe(self) -> None:
        raise BrokenPipeError


def _did_you_mean(message: str) -> str:
    """argparse's "invalid choice: 'rnu' (choose from 'run', …)", with the choice the user most likely meant."""
    found = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
    if not found:
        return ""
    close = difflib.get_close_matches(found.group(1), re.findall(r"'([^']*)'", found.group(2)), n=1)
    return f" — did you mean '{close[0]}'?" if close else ""


def _default_action(argv: list[str]) -> list[str]:
    """``hil history`` alone (or with only options) lists the runs, as ``hil history list`` does."""
    if "history" in argv:
        at = argv.index("history") + 1
        if at == len(argv) or (argv[at].startswith("-") and argv[at] not in ("-h", "--help")):
            return [*argv[:at], "list", *argv[at:]]
    return argv


def _command_parser(parser: argparse.ArgumentParser, argv: list[str]) -> argparse.ArgumentParser:
    """The parser of the (sub-)command ``argv`` names — ``hil history trend`` — whose usage an error shows."""
    found = parser
    for command in commands(parser):
        words = command.prog.split()[1:]
        if words and [a for a in argv if not a.startswith("-")][:len(words)] == words:
            found = command.parser
    return found


def _unknown(parser: argparse.ArgumentParser, argv: list[str], unknown: list[str], command: str) -> None:
    """Options the command does not know, said by that command's parser: a close option of its own first (a
    typo: ``--bnech`` → ``--bench``), else, for ``hil run``, that pytest's options go after ``--``."""
    own = _command_parser(parser, argv)
    options = [o for a in own._actions for o in a.option_strings]
    typos = {u: difflib.get_close_matches(u.split("=")[0], options, n=1) for u in unknown if u.startswith("--")}
    said = [f"{u} (did you mean {c[0]}?)" for u, c in typos.items() if c]
    if said:
        own.error(f"unrecognized arguments: {', '.join(said)}")
    if command == "run":
        own.error(f"unrecognized arguments: {' '.join(unknown)} — pytest's own options go after '--', "
                  f"e.g. hil run -- {' '.join(_after_run(argv))}")
    own.error(f"unrecognized arguments: {' '.join(unknown)}")


def main(argv: list[str] | None = None) -> int:
    argv = _default_action(sys.argv[1:] if argv is None else list(argv))
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        _unknown(parser, argv, unknown, args.command)
    if not args.debug:
        # pymodbus logs its own retries and timeouts ("No response received after 0 retries…") to stderr; the
        # command's one-line error says what failed and what to check.  --debug shows them.
        logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    console = _Console(stderr=False)
    try:
        return dispatch(args, console)
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        return _reader_left(args.command)
    except (HilError, OSError) as exc:
        # what the user can act on (a bad profile, an unreachable PLC, a missing port): one line
        if args.debug:
            traceback.print_exc()
        # soft_wrap: one line whatever the width; escape: messages quote "[sections]" that are not markup
        Console(stderr=True, soft_wrap=True).print(f"[bold red]hil {args.command}:[/] {escape(one_line(exc))}",
                                                   highlight=False)
        return EXIT_USAGE
    except Exception:  # noqa: BLE001 - anything else is a bug in hil: the traceback, to report
        traceback.print_exc()
        print(f"hil {args.command}: internal error (a bug in hil {__version__}): please report it with the "
              f"traceback above", file=sys.stderr)
        return EXIT_INTERNAL


def _after_run(argv: list[str]) -> list[str]:
    rest = argv[argv.index("run") + 1:] if "run" in argv else argv
    return [a for a in rest if a != "--"]


def one_line(exc: BaseException) -> str:
    """The error as one line: what failed and what to do (hil's messages say both)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, PermissionError) and exc.filename:
        return f"cannot open {exc.filename}: permission denied — check its owner and mode (serial ports: add " \
               f"your user to the dialout group)"
    if isinstance(exc, FileNotFoundError) and exc.filename:
        return f"{exc.filename}: no such file — check the path"
    return text


def _given(value: str | None, what: str) -> str | None:
    """A URL the command line gives; an empty one is refused (it must not quietly mean the profile's)."""
    if value is not None and not value.strip():
        raise InvalidValue(f"{what} is empty: give a target URL (e.g. emulator+fatek-tcp, fatek+tcp://HOST:500), or "
                           f"leave it out to use the bench profile's target")
    return value


def dispatch(args: argparse.Namespace, console: Console) -> int:
    for name in ("url", "target"):
        if hasattr(args, name):
            _given(getattr(args, name), "--target" if name == "target" else "the target URL")
    if args.command == "init":
        from hil.cli.init import init
        return init(args.url, Path(args.dir), console, name=args.name, table=args.temperature_table,
                    scratch=tuple(args.scratch),
                    time_scale=args.time_scale, force=args.force)
    if args.command == "run":
        from hil.cli.run import run
        extra = args.pytest_args[1:] if args.pytest_args[:1] == ["--"] else args.pytest_args
        lab = {"place": args.lg_place, "reserve": args.lg_reserve, "coordinator": args.lg_coordinator,
               "wait": args.lg_wait}
        if args.bench and len(args.bench) > 1:
            if args.lg_place or args.lg_reserve:
                raise InvalidValue("--lg-place/--lg-reserve name one place for one bench: with several --bench, "
                                   "name each bench's place in its profile's [labgrid] section")
            if args.lanes is not None:
                raise InvalidValue("--lanes runs one bench's lanes side by side: several --bench already run in "
                                   "parallel, one process each — give --lanes with one --bench")
            from hil.cli.many import run_many
            return run_many(args.bench, args.target, args.junitxml, extra, console, html=args.html)
        args.bench = args.bench[0] if args.bench else None
        from hil.bench.profile import check_profile, lab_request
        spec = lab_request(args.bench or default_bench(), place=args.lg_place, tags=args.lg_reserve,
                           coordinator=args.lg_coordinator, wait=args.lg_wait)
        if args.bench or spec is not None:  # a bad profile: one line here, before pytest starts (and before a queue)
            check_profile(args.bench or default_bench(), spec)
        if args.lanes is not None:
            if args.lanes < 1:
                raise InvalidValue(f"--lanes {args.lanes}: give 1 or more (1: one process, as without --lanes)")
            if args.lanes > 1:
                extra = ["-n", str(args.lanes), "--dist", "each", *extra]
        return run(args.bench, args.target, args.junitxml, extra, html=args.html, operator=args.operator,
                   station=args.station, trace=args.trace, verbosity=args.verbose - args.quiet, color=args.color,
                   lab=lab)
    if args.command == "emulate":
        from hil.cli.emulate import emulate
        given = {name: getattr(args, f"wire:{name}") for name in WIRES}
        tcp = [w for w in WIRES.values() if w.kind != "pty"]  # TCP endpoints first, then the ptys (their order)
        endpoints = [(w.name, given[w.name]) for w in tcp if given[w.name]]
        endpoints += [(w.name, None) for w in WIRES.values() if w.kind == "pty" and given[w.name]]
        if not endpoints:
            flags = [w.option + ("" if w.kind == "pty" else " HOST:PORT") for w in WIRES.values()]
            raise InvalidValue(f"nothing to serve: give {', '.join(flags[:-1])} or {flags[-1]} (the profile's "
                               f"family serves some of them)")
        return emulate(args.bench or str(default_bench()), endpoints, args.time_scale, args.rig_modbus_tcp,
                       args.rig_first_coil, live=not args.no_live and console.is_terminal, line=args.line,
                       timing=args.timing, seed=args.seed)
    if args.command == "probe":
        from hil.cli.probe import probe
        return probe(args.url, console, bench=args.bench)
    if args.command == "rtc":
        from hil.cli import rtc
        if args.rtc_command == "read":
            return rtc.rtc_read(args.url, console, bench=args.bench)
        if args.rtc_command == "set":
            return rtc.rtc_set(args.url, args.time, console, bench=args.bench)
        return rtc.rtc_sync(args.url, console, bench=args.bench)
    if args.command == "list":
        from hil.cli.listing import list_all
        return list_all(console)
    if args.command == "restore":
        from hil.cli.restore import restore
        return restore(args.url, args.bench, console, show=args.show, accept_host_clock=args.accept_host_clock)
    if args.command == "history":
        from hil.cli.history import history
        return history(args, console)
    if args.command == "spec":
        from hil.cli.spec import spec
        return spec(Path(args.suites) if args.suites else project_dir("suites"), console, verbose=args.verbose)
    if args.command == "drift":
        from hil.cli import rtc
        if args.drift_command == "code":
            return rtc.drift_code(args.rate, console)
        if args.drift_command == "decode":
            return rtc.drift_decode(args.code, console)
        return rtc.drift_measure(args.url, args.duration, console, bench=args.bench, apply=args.apply)
    raise AssertionError(args.command)


if __name__ == "__main__":
    sys.exit(main())
