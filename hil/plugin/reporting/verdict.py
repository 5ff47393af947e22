"""The run's verdict, read from pytest's own session status — never from a count of the tests that reported.

An interrupted run (SIGINT; SIGTERM and SIGHUP unwind the same way, :mod:`hil.core.signals`), a crashed one (an
internal error in pytest or a plugin) and one stopped early (``-x``, a bench that cannot be opened) must say so in
every output.  Two causes made such runs read PASSED:

* the test that was running when the run stopped never got a report (pytest lets KeyboardInterrupt and internal
  errors pass its report), so pytest's JUnit wrote a nameless ``<testcase time="0.001"/>``, its counts left the test
  out, and hil's record of it, made when it started, stayed "passed";
* the HTML badge was computed from those records, not from the session's exit status.

:class:`Stops` gives the unfinished test the report it lacked — through pytest's own ``pytest_runtest_logreport``,
so pytest's terminal counts, its JUnit file and hil's records are the same counts — and keeps what stopped the run;
:func:`verdict` reads the session's exit status.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import pytest

#: pytest's exit status (pytest.ExitCode, also ``hil run``'s) → the verdict every report shows
STATUS = {0: "PASSED", 1: "FAILED", 2: "INTERRUPTED", 3: "INTERNAL ERROR", 4: "USAGE ERROR", 5: "NO TESTS RAN"}
#: what a report says before its run has finished, and keeps saying when the run died without finishing it
INCOMPLETE = "INCOMPLETE"
Phase = Literal["setup", "call", "teardown"]  # a test's phases, as pytest.TestReport.when names them
_PHASES: tuple[Phase, ...] = ("setup", "call", "teardown")


def status_of(exit_status: int | None) -> str:
    """``PASSED`` for 0, ``INTERRUPTED`` for 2 …; a run that left no exit status never finished."""
    if exit_status is None:
        return INCOMPLETE
    return STATUS.get(int(exit_status), f"EXIT {int(exit_status)}")


@dataclass(frozen=True)
class Verdict:
    """What a run's reports say of it as a whole."""

    status: str  # STATUS's values or INCOMPLETE
    stopped: str = ""  # what stopped the run before its end ("" when it ran to the end)
    not_run: int = 0  # collected tests that never started
    plc: str = ""  # whether the PLC is as it was found, said when the run was stopped or left something changed

    @property
    def passed(self) -> bool:
        return self.status == "PASSED"

    def line(self) -> str:
        """``INTERRUPTED — SIGINT received during suites/x.py::test_y (call); 3 tests did not run; …``"""
        parts = [self.stopped] if self.stopped else []
        if self.not_run:
            parts.append(f"{self.not_run} test{'s' if self.not_run != 1 else ''} did not run")
        if self.plc:
            parts.append(self.plc)
        return self.status + (" — " + "; ".join(parts) if parts else "")

    def properties(self) -> list[tuple[str, str]]:
        """The JUnit testsuite properties: ``hil.verdict`` always, ``hil.stopped`` / ``hil.not_run`` /
        ``hil.plc_restored`` when they say something."""
        out = [("hil.verdict", self.status)]
        if self.stopped:
            out.append(("hil.stopped", self.stopped))
        if self.not_run:
            out.append(("hil.not_run", str(self.not_run)))
        if self.plc:
            out.append(("hil.plc_restored", self.plc))
        return out


def incomplete(started: str) -> Verdict:
    """The verdict a report carries while its run is under way (a run killed with SIGKILL, or by pytest-timeout's
    thread method, never replaces it: its reports must not keep an earlier run's PASSED)."""
    return Verdict(INCOMPLETE, f"the run started {started} and did not finish (still running, or killed before "
                               f"its end: then the next run on this bench restores the PLC from its journal)")


def describe(exc: BaseException) -> str:
    """What stopped the run, as a report says it: ``SIGINT received``, ``internal error: ValueError: …``."""
    if isinstance(exc, KeyboardInterrupt):
        return str(exc) or "interrupted (KeyboardInterrupt)"
    if isinstance(exc, pytest.exit.Exception):
        return f"pytest.exit(): {exc}"
    text = " ".join(str(exc).split())
    return f"internal error (in pytest or a plugin): {type(exc).__name__}" + (f": {text}" if text else "")


class Stops:
    """Watches each test's phases; when the run stops inside a test, logs that test's missing report."""

    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.stopped = ""
        self._stopped_in: Path | None = None  # the file of the test the run stopped in
        self._phase: tuple[str, Phase, float] | None = None  # (nodeid, phase, started) of the phase under way
        self._reported: set[tuple[str, str]] = set()
        self._ran: set[str] = set()
        self._made: set[tuple[str, str]] = set()  # (nodeid, phase) of the reports given to stopped tests

    def aborted(self, report: pytest.TestReport) -> bool:
        """Whether ``report`` is the one given to a test the run stopped inside (it has no result)."""
        return (report.nodeid, report.when) in self._made

    def not_run(self, items: list[pytest.Item]) -> int:
        return sum(1 for item in items if item.nodeid not in self._ran)

    def _enter(self, item: pytest.Item, when: Phase) -> None:
        self._phase = (item.nodeid, when, time.time())

    @pytest.hookimpl(tryfirst=True)
    def pytest_runtest_setup(self, item: pytest.Item) -> None:
        self._enter(item, "setup")

    @pytest.hookimpl(tryfirst=True)
    def pytest_runtest_call(self, item: pytest.Item) -> None:
        self._enter(item, "call")

    @pytest.hookimpl(tryfirst=True)
    def pytest_runtest_teardown(self, item: pytest.Item) -> None:
        self._enter(item, "teardown")

    @pytest.hookimpl(tryfirst=True)
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        self._reported.add((report.nodeid, report.when))
        self._ran.add(report.nodeid)

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_protocol(self, item: pytest.Item, nextitem: pytest.Item | None) -> Any:
        try:
            return (yield)
        except BaseException as exc:  # noqa: BLE001 - re-raised below, once the unfinished test is reported
            stop = exc
        # outside the except block: the teardown run below must not chain its own errors to the stop
        self.stopped = self.stopped or f"{describe(stop)} during {item.nodeid}"
        self._stopped_in = getattr(item, "path", None)
        with contextlib.suppress(Exception):  # the exception that stopped the run is the one pytest must see
            self._report_unfinished(item, stop)
        raise stop

    @pytest.hookimpl(tryfirst=True)  # before the terminal reporter keeps its picture of the interrupt
    def pytest_keyboard_interrupt(self, excinfo: pytest.ExceptionInfo) -> None:
        self.stopped = self.stopped or describe(excinfo.value)  # between tests, or during collection
        if self._stopped_in is not None and not self.config.option.fulltrace:
            # pytest's "<file>:<line>: KeyboardInterrupt" names the test's line the run was at, not the wire
            # read or the sleep inside hil it was waiting in (--full-trace shows those)
            entries = [i for i, entry in enumerate(excinfo.traceback) if entry.path == self._stopped_in]
            if entries:
                excinfo.traceback = excinfo.traceback[:entries[-1] + 1]

    def pytest_internalerror(self, excrepr: Any, excinfo: pytest.ExceptionInfo) -> None:
        self.stopped = self.stopped or describe(excinfo.value)  # returns None: pytest still prints it

    def _report_unfinished(self, item: pytest.Item, exc: BaseException) -> None:
        phase: tuple[str, Phase, float] = self._phase if self._phase and self._phase[0] == item.nodeid else \
            (item.nodeid, "setup", time.time())
        nodeid, when, started = phase
        while (nodeid, when) in self._reported:  # that phase reported; the run stopped in the next one
            if when == "teardown":
                return  # the test finished: what stopped the run came after it
            when = _PHASES[_PHASES.index(when) + 1]
        where = _where(exc, item)
        text = (f"{describe(exc)} during {when}{f' at {where}' if where else ''}: the test did not finish, so it has "
                f"no result")
        now = time.time()
        report = pytest.TestReport(nodeid, item.location, dict.fromkeys(item.keywords, 1), "failed", text, when,
                                   duration=now - started, start=started, stop=now,
                                   user_properties=list(item.user_properties))
        self._made.add((nodeid, when))
        item.ihook.pytest_runtest_logreport(report=report)
        if when != "teardown":
            self._teardown(item)

    @staticmethod
    def _teardown(item: pytest.Item) -> None:
        """The stopped test's teardown now, as its own reported phase (pytest would leave it to the session's end,
        unreported): its restore's outcome is the test's, in every count."""
        call = pytest.CallInfo.from_call(lambda: item.ihook.pytest_runtest_teardown(item=item, nextitem=None),
                                         "teardown")
        item.ihook.pytest_runtest_logreport(report=item.ihook.pytest_runtest_makereport(item=item, call=call))


def _where(exc: BaseException, item: pytest.Item) -> str:
    """``test_x.py:12`` — the last line of the test's own file the exception passed through."""
    path = str(getattr(item, "path", ""))
    tb, found = exc.__traceback__, ""
    while tb is not None:
        if tb.tb_frame.f_code.co_filename == path:
            found = f"{Path(path).name}:{tb.tb_lineno}"
        tb = tb.tb_next
    return found


__all__ = ["Verdict", "Stops", "STATUS", "INCOMPLETE", "status_of", "incomplete", "describe"]
