"""Bench safety in a pytest session (issue 15): recovery said loudly, signals that unwind, and a session that
ends non-zero naming every element it could not put back.

* A journal a dead run left is replayed when the bench opens (``BenchSession._recover``); :func:`announce` prints
  that on the console whatever the verbosity, records it as the JUnit testsuite property ``hil_bench_recovery``,
  and a ``bench_recovery`` testcase runs first and fails if the recovery failed.
* SIGTERM and SIGHUP unwind like Ctrl-C; a signal during a restore waits for it (:mod:`hil.core.signals`).
* At the end of the session every restore that failed is retried; what is still not restored is listed and the
  exit status is non-zero.

PYTEST_DONT_REWRITE (no asserts here: see ``pytest_plugins`` in :mod:`hil.plugin.pytest_plugin`)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest

from hil.bench.base import BenchBase
from hil.bench.replay import Recovery
from hil.core import signals
from hil.plugin.stash import BENCH_SESSION

#: what recovery said this session, for the reports (the JUnit testsuite property hil_bench_recovery)
RECOVERY_NOTES = pytest.StashKey[list]()
#: whether the PLC is as it was found once the session ended (set only when a bench was opened): the verdict
#: (hil.plugin.reporting.verdict) says it after a run that was stopped
PLC_LEFT = pytest.StashKey[str]()
AS_FOUND = "the PLC is as it was found (every value written was put back and read back)"


def say(config: pytest.Config, text: str, **markup: bool) -> None:
    """A line of the bench's safety on the console, whatever the verbosity (stderr without a terminal reporter)."""
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.ensure_newline()
        reporter.write_line(text, **markup)
    else:
        print(text, file=sys.stderr)


def announce(config: pytest.Config, recovery: Recovery) -> None:
    text = recovery.summary()
    config.stash.setdefault(RECOVERY_NOTES, []).append(text)
    say(config, text, bold=True, red=not recovery.ok, yellow=recovery.ok)


class BenchRecoveryFailed(Exception):
    pass


class BenchRecoveryItem(pytest.Item):
    """The ``bench_recovery`` testcase: fails when a dead run's leftovers could not be restored."""

    def __init__(self, *, recovery: Recovery, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.recovery = recovery
        self.user_properties.append(("hil_bench_recovery", recovery.summary()))

    def runtest(self) -> None:
        if not self.recovery.ok:
            raise BenchRecoveryFailed(self.recovery.summary())

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException], style: str | None = None) -> str:
        return str(excinfo.value)

    def reportinfo(self) -> tuple[Path, None, str]:
        return self.path, None, "bench_recovery"


def pytest_sessionstart(session: pytest.Session) -> None:
    signals.install()


@pytest.hookimpl(trylast=True)
def pytest_collection_finish(session: pytest.Session) -> None:
    state = session.config.stash.get(BENCH_SESSION, None)
    recovery = getattr(state, "recovery", None)
    if recovery is not None and recovery.needed:
        # nodeid "hil.bench::bench_recovery": JUnit's classname hil.bench (a bare name gives an empty classname)
        session.items.insert(0, BenchRecoveryItem.from_parent(session, name="bench_recovery",
                                                              nodeid="hil.bench::bench_recovery", recovery=recovery))


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """After every fixture's teardown: retry what is still unrestored; list what stays, and fail the session."""
    state = session.config.stash.get(BENCH_SESSION, None)
    bench = getattr(state, "bench", None)
    if bench is None or not hasattr(bench, "io"):
        return
    error = None
    retried = bool(_unrestored(bench, exact=False))
    with signals.shielded():
        try:
            if retried:
                bench.end_test()  # idempotent: faults, the clock, then the journaled elements, each verified
        except Exception as exc:  # noqa: BLE001 - said below, with what stays unrestored
            error = exc
        try:
            bench.finish()  # what each test put back only approximately (the clock's phase), now exactly
        except Exception as exc:  # noqa: BLE001 - said below, with what stays unrestored
            error = exc
    left = _unrestored(bench)
    session.config.stash[PLC_LEFT] = AS_FOUND if not left else (
        f"the PLC is NOT as it was found: {len(left)} element{'s' if len(left) != 1 else ''} still changed")
    if error is None and not left:
        return
    if not left:
        if retried:
            say(session.config, "hil: every value a failed restore had left changed was restored at the end of "
                                "the session", yellow=True)
        return
    journal = getattr(bench, "journal", None)
    where = f" (kept in {journal.path}; the next run or `hil restore` puts them back)" if journal is not None else ""
    text = f"hil: the PLC is NOT as it was found — still unrestored{where}: {'; '.join(left)}"
    if error is not None:
        text += f" — last error: {error}"
    say(session.config, text, bold=True, red=True)
    if session.exitstatus == 0:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def _unrestored(bench: BenchBase, exact: bool = True) -> list[str]:
    """What is still not as it was found; ``exact=False`` leaves out a clock put back to within half a second
    (the session's end makes it exact) and a working state held still (the run stopped inside a module that holds
    one: its end puts that back, no failed restore left it)."""
    io = bench.io
    held = set() if exact else {*getattr(io, "held", ()), *(["clock"] if getattr(io, "clock_held", False) else [])}
    # the clock too, while a test has it set
    out = [f"{a} (original {v})" for a, v in getattr(io, "unrestored", []) if a not in held]
    origin = getattr(io, "clock_origin", None)
    if exact and origin is not None and not getattr(io, "clock_due", False):
        out.append(f"clock (original {origin.plc:%Y-%m-%d %H:%M:%S}, to be put back exactly at its offset from host "
                   f"time)")
    faults = getattr(bench, "faults", None)
    for injector in getattr(faults, "_made", {}).values():
        for point in sorted(getattr(injector, "opened", ())):
            out.append(f"{injector.kind} fault on point {point}")
    return out


def pytest_unconfigure(config: pytest.Config) -> None:
    signals.uninstall()
