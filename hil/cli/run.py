"""``hil run``: the suites against a bench, with JUnit XML, an HTML report and wire traces in reports/."""

from __future__ import annotations

import argparse
from collections.abc import Generator
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

from hil.bench.profile import check_profile, lab_request, refuse_default_for_a_plc
from hil.cli.many import run_many
from hil.cli.parser import Subparsers
from hil.core.errors import ERROR_PREFIX, InvalidValue, error_line
from hil.core.paths import default_bench, suite_path, suites_dir

#: pytest options whose value is the next argument (so that value is not a test path): ``-k rtc``, ``-m slow``…
_TAKES_VALUE = {"-k", "-m", "-p", "-o", "-c", "-W", "-r", "--deselect", "--ignore", "--ignore-glob", "--rootdir",
                "--confcutdir", "--basetemp", "--bench", "--target", "--junitxml", "--junit-xml", "--hil-html",
                "--operator", "--station", "--hil-trace", "--hil-trace-dir", "--hil-lock-wait", "--maxfail",
                "--timeout", "--durations", "-n", "--numprocesses", "--dist", "--max-worker-restart", "--tb", "--color",
                "--log-level", "--override-ini", "--pyargs",
                "--import-mode", "--capture", "--cache-show", "--lfnf", "--last-failed-no-failures",
                "--hil-records", "--hil-lg-place", "--hil-lg-reserve", "--hil-lg-coordinator",
                "--hil-lg-wait"}


def selects_tests(extra: list[str]) -> bool:
    """Whether the pytest arguments name test files, directories or ids of their own: then only those run
    (on a real bench, running every suite instead means writes nobody asked for)."""
    return bool(_test_args(extra))


def _test_args(extra: list[str]) -> list[int]:
    """The positions of the arguments that name tests (not options, nor an option's value)."""
    found, previous = [], ""
    for n, arg in enumerate(extra):
        if not arg.startswith("-") and previous not in _TAKES_VALUE and (_names_tests(arg) or suite_path(arg)):
            found.append(n)
        previous = arg if "=" not in arg else ""
    return found


def with_suite_names(extra: list[str]) -> tuple[list[str], bool]:
    """The arguments with each suite's short name (``rtc``, ``s7smart``) and each ``suites/…`` path this directory
    lacks replaced by the bundled suite's path; and whether every test they name is one of the suites (then the
    suites' directory's parent is pytest's rootdir, so test ids read ``suites/test_rtc.py::…`` wherever hil is
    installed and whatever the current directory)."""
    extra, ours = list(extra), True
    root = suites_dir()
    for n in _test_args(extra):
        extra[n] = suite_path(extra[n]) or extra[n]
        path = Path(extra[n].partition("::")[0]).absolute()
        ours = ours and (path == root or root in path.parents)
    return extra, ours


def _names_tests(arg: str) -> bool:
    """A test file, directory or id (an option's value of an unknown option is none of those)."""
    path = arg.split("::", 1)[0]
    return "::" in arg or path.endswith(".py") or Path(path).exists()


def pytest_args(bench: str | None, target: str | None, junitxml: str, extra: list[str], *,
                html: str | None = None, operator: str | None = None, station: str | None = None,
                trace: str | None = None, verbosity: int = 0, color: str | None = None,
                lab: dict[str, object] | None = None) -> list[str]:
    """``lab``: ``hil run``'s ``--lg-place`` / ``--lg-reserve`` / ``--lg-coordinator`` / ``--lg-wait``, by their
    names without the prefix, for the plugin (:mod:`hil.plugin.lab`: ``--hil-lg-…``)."""
    extra, ours = with_suite_names(extra)
    paths = [] if selects_tests(extra) else [str(suites_dir())]
    if ours and not any(a == "--rootdir" or a.startswith("--rootdir=") for a in extra):
        paths.append(f"--rootdir={suites_dir().parent}")
    # The cache provider stays on (--lf, --ff, --sw work), its directory here, never inside an installed package
    cache = Path.cwd() / ".pytest_cache"
    args = [*paths, "--bench", bench or str(default_bench()), f"--junitxml={junitxml}",
            "-o", "junit_family=xunit1", "-o", f"cache_dir={cache}"]
    given = {"--target": target, "--hil-html": html, "--operator": operator, "--station": station,
             "--hil-trace": trace}
    args += [arg for option, value in given.items() if value for arg in (option, value)]
    if verbosity:
        args.append("-" + ("v" if verbosity > 0 else "q") * abs(verbosity))
    if color:
        args.append(f"--color={color}")
    args += [f"--hil-lg-{name}={value}" for name, value in (lab or {}).items() if value is not None]
    # labgrid's own pytest plugin (installed with hil[labgrid]) would import labgrid's gRPC client into this process
    # and reformat pytest's logging: hil runs labgrid-client as a program (hil.bench.lab.client)
    args += ["-p", "no:labgrid"]
    return args + extra


def given(extra: list[str], option: str) -> str | None:
    """The value the pytest arguments give ``option`` (``--target URL`` or ``--target=URL``; the last, as pytest
    takes it), None when they do not name it."""
    found = None
    for n, arg in enumerate(extra):
        if arg == option and n + 1 < len(extra):
            found = extra[n + 1]
        elif arg.startswith(option + "="):
            found = arg.partition("=")[2]
    return found


def run(bench: str | None, target: str | None, junitxml: str, extra: list[str], **options: Any) -> int:
    """The suites in this process, by pytest; ``options``: :func:`pytest_args`'s."""
    # before pytest is given the default by name; `hil run -- --target URL` names a PLC as much as --target does
    refuse_default_for_a_plc(given(extra, "--target") or target, given(extra, "--bench") or bench, default_bench())
    Path(junitxml).parent.mkdir(parents=True, exist_ok=True)
    for own in (junitxml, options.get("html")):  # an earlier run's result must not pass for this one's, even if
        if own:  # this one dies before its reports say INCOMPLETE (hil.plugin.reporting.verdict)
            Path(str(own)).unlink(missing_ok=True)
    return int(pytest.main(pytest_args(bench, target, junitxml, extra, **options), plugins=[PytestsUsageErrors()]))


class PytestsUsageErrors:
    """Under ``hil run``, pytest's own usage errors found in its run (a test path that does not exist) are said in
    hil's one error line too: the user typed hil's command.  (hil.plugin.usage's wrapper, outside this one, prints
    it.)"""

    @pytest.hookimpl(wrapper=True)
    def pytest_cmdline_main(self, config: pytest.Config) -> Generator[None, object, object]:
        try:
            return (yield)
        except pytest.UsageError as exc:
            raise pytest.UsageError(*(error_line(f"pytest: {line}", "check the arguments after '--' (hil run --help)")
                                      if not str(line).startswith(ERROR_PREFIX) else line
                                      for line in exc.args)) from None


# -- the command line -----------------------------------------------------------------------------------------------
def add_parser(sub: Subparsers, summary: str) -> None:
    run = sub.add_parser("run", help=summary,
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
                          "-n N --dist each; hil.plugin.lanes): the RTC suites beside the temperature and PID ones; on "
                          "port 0 at 9600 bit/s one fills the line while the other waits for the PLC "
                          "(docs/performance.md)")
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

    run.set_defaults(func=command)


def command(args: argparse.Namespace, console: Console) -> int:
    """``hil run``: several ``--bench`` in parallel (one process each), else this bench's suites in this process."""
    extra = args.pytest_args[1:] if args.pytest_args[:1] == ["--"] else args.pytest_args
    if args.bench and len(args.bench) > 1:
        _refuse_per_bench_options(args)
        return run_many(args.bench, args.target, args.junitxml, extra, console, html=args.html)
    bench = args.bench[0] if args.bench else None
    lab = {"place": args.lg_place, "reserve": args.lg_reserve, "coordinator": args.lg_coordinator,
           "wait": args.lg_wait}
    _check_profile_first(bench, args)
    return run(bench, args.target, args.junitxml, [*_lanes(args.lanes), *extra], html=args.html,
               operator=args.operator, station=args.station, trace=args.trace, verbosity=args.verbose - args.quiet,
               color=args.color, lab=lab)


def _refuse_per_bench_options(args: argparse.Namespace) -> None:
    """Options that name one bench's place or lanes mean nothing for several benches at once."""
    if args.lg_place or args.lg_reserve:
        raise InvalidValue("--lg-place/--lg-reserve name one place for one bench: with several --bench, "
                           "name each bench's place in its profile's [labgrid] section")
    if args.lanes is not None:
        raise InvalidValue("--lanes runs one bench's lanes side by side: several --bench already run in "
                           "parallel, one process each — give --lanes with one --bench")


def _check_profile_first(bench: str | None, args: argparse.Namespace) -> None:
    """A bad profile is one line here, before pytest starts (and before a labgrid queue)."""
    spec = lab_request(bench or default_bench(), place=args.lg_place, tags=args.lg_reserve,
                       coordinator=args.lg_coordinator, wait=args.lg_wait)
    if bench or spec is not None:
        check_profile(bench or default_bench(), spec)


def _lanes(lanes: int | None) -> list[str]:
    """pytest-xdist's arguments for ``--lanes N``: N processes, each running every lane's tests it is given."""
    if lanes is None or lanes == 1:
        return []
    if lanes < 1:
        raise InvalidValue(f"--lanes {lanes} — give 1 or more (1: one process, as without --lanes)")
    return ["-n", str(lanes), "--dist", "each"]
