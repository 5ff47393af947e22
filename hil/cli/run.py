"""``hil run``: the suites against a bench, with JUnit XML, an HTML report and wire traces in reports/."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.bench.profile import refuse_default_for_a_plc
from hil.core.paths import default_bench, suite_path, suites_dir

#: pytest options whose value is the next argument (so that value is not a test path): ``-k rtc``, ``-m slow``…
_TAKES_VALUE = {"-k", "-m", "-p", "-o", "-c", "-W", "-r", "--deselect", "--ignore", "--ignore-glob", "--rootdir",
                "--confcutdir", "--basetemp", "--bench", "--target", "--junitxml", "--junit-xml", "--hil-html",
                "--operator", "--station", "--hil-trace", "--hil-trace-dir", "--hil-lock-wait", "--maxfail",
                "--timeout", "--durations", "-n", "--numprocesses", "--dist", "--max-worker-restart", "--tb", "--color", "--log-level", "--override-ini", "--pyargs",
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
    if target:
        args += ["--target", target]
    if html:
        args += ["--hil-html", html]
    if operator:
        args += ["--operator", operator]
    if station:
        args += ["--station", station]
    if trace:
        args += ["--hil-trace", trace]
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


def run(bench: str | None, target: str | None, junitxml: str, extra: list[str], **options: object) -> int:
    # before pytest is given the default by name; `hil run -- --target URL` names a PLC as much as --target does
    refuse_default_for_a_plc(given(extra, "--target") or target, given(extra, "--bench") or bench, default_bench())
    Path(junitxml).parent.mkdir(parents=True, exist_ok=True)
    for own in (junitxml, options.get("html")):  # an earlier run's result must not pass for this one's, even if
        if own:  # this one dies before its reports say INCOMPLETE (hil.plugin.reporting.verdict)
            Path(str(own)).unlink(missing_ok=True)
    return int(pytest.main(pytest_args(bench, target, junitxml, extra, **options)))  # type: ignore[arg-type]
