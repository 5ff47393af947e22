"""The pytest plugin that records each session in the history (entry point ``hil-history``).

It reads what the reporting plugin (``hil-reporter``) already holds — the testsuite properties, each test's
record with its measurements, the verdict — and writes it as the run goes: the run when its tests start, each test
after its teardown, the verdict at the end.  Before the HTML report is written it gives the reporter the bench's
history (:mod:`hil.history.annotate`).

Recording never fails a run: the first error of the store is reported once (one line), and the rest of the run —
its row and its tests so far included — goes to the local spool, which ``hil history sync`` uploads later.
"""

from __future__ import annotations

import datetime as dt
import os
import socket
from pathlib import Path
from typing import Any

import pytest

from hil.history import config as history_config

#: the last values shown beside each measurement in the HTML report
SPARK_RUNS = 10
#: each run's HTML report is kept in this folder beside the report (the next report links it)
ARCHIVE = "history"


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("hil-report")
    group.addoption("--hil-history", metavar="URL", default=None,
                    help="record the run in this history store (sqlite:///PATH, postgresql://USER@HOST/DB), or "
                         "'off' (default $HIL_HISTORY_URL, else the profile's [history] url, else SQLite in hil's "
                         "state directory)")


@pytest.hookimpl(trylast=True)
def pytest_configure(config: pytest.Config) -> None:
    if getattr(config, "workerinput", None) is not None:
        return  # an xdist worker: the controller records
    config.pluginmanager.register(Recorder(config), "hil-history-recorder")


class Recorder:
    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.store: Any = None  # hil.history.store.Store while recording
        self.url = ""
        self.run_id: int | None = None
        self.info: Any = None  # hil.history.store.RunInfo
        self.attempts: dict[str, int] = {}
        self.warned = False
        self.spooled = False
        self._unsent: list[Any] = []  # tests written before the store failed: sent again to the spool

    # -- the start ----------------------------------------------------------------------------------------------
    @pytest.hookimpl(tryfirst=True)
    def pytest_runtestloop(self, session: pytest.Session) -> None:
        reporter = self._reporter()
        if reporter is None or not reporter.uses_bench or self.config.option.collectonly:
            return
        state = reporter._state()
        profile = getattr(state, "profile", None)
        try:
            url = history_config.resolve(self.config.getoption("--hil-history"),
                                         getattr(profile, "history_url", None))
        except Exception as exc:  # noqa: BLE001 - a bad URL is said once; the run goes on
            self._warn(f"history off: {exc}")
            return
        if url is None:
            return
        from hil.history.store import RunInfo
        bench = dict(reporter.properties).get("hil.bench") or getattr(profile, "name", "") or "bench"
        self.info = RunInfo(bench, list(reporter.properties), host=socket.gethostname(), pid=os.getpid())
        self.info.report = self._archive_path(reporter)
        self.url = url
        self._try(self._open_and_start, url)

    def _open_and_start(self, url: str) -> None:
        from hil.history.store import Store
        self.store = Store(url)
        self.run_id = self.store.start_run(self.info)

    # -- each test ----------------------------------------------------------------------------------------------
    @pytest.hookimpl(trylast=True)  # after the reporter has taken the teardown's report into its record
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if report.when != "teardown" or self.info is None:
            return
        reporter = self._reporter()
        record = reporter.records.get(report.nodeid) if reporter is not None else None
        if record is None:
            return
        from hil.history.store import TestResult
        self.attempts[report.nodeid] = attempt = self.attempts.get(report.nodeid, 0) + 1
        skip = ("hil.measure.", "hil.trace_file", "hil.attachment.")
        extra = {k: v for k, v in report.user_properties if not str(k).startswith(skip)}
        result = TestResult(record.nodeid, record.outcome, area=record.area, duration=record.duration,
                            attempt=attempt, requirements=list(record.requirements), message=record.message,
                            properties=extra, measurements=[m for m in record.measurements])
        self._unsent.append(result)
        self._try(self._flush)

    def _flush(self) -> None:
        """The tests not yet in the store (normally just the one that finished), in one transaction."""
        with self.store.engine.begin() as conn:
            for result in self._unsent:
                self.store.add_test(self.run_id, result, conn)
        self._unsent.clear()

    # -- the end ------------------------------------------------------------------------------------------------------
    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        """Inside the reporter's wrapper, before it writes the HTML report: the bench's history for that report."""
        reporter = self._reporter()
        if reporter is None or self.info is None or self.store is None:
            return
        from hil.history.annotate import Annotations

        def read() -> None:
            last, values = self.store.bench_history(self.info.bench, self.run_id, SPARK_RUNS)
            reporter.annotations = Annotations.build(last, values, reporter.records.values(),
                                                     html=reporter.html_path, store=self.store.shown,
                                                     spooled=self.spooled)
        self._try(read)

    def pytest_unconfigure(self, config: pytest.Config) -> None:
        reporter = self._reporter()
        if self.info is None or self.store is None:
            return
        verdict = getattr(reporter, "verdict", None)
        report = self.info.report
        written = getattr(reporter, "html_written", None)
        if report and written is not None:
            try:
                Path(report).parent.mkdir(parents=True, exist_ok=True)
                page = Path(written).read_text(encoding="utf-8")
                # the copy sits beside the earlier ones: its link to the previous report is relative to there
                Path(report).write_text(page.replace(f'href="{ARCHIVE}/', 'href="'), encoding="utf-8")
            except OSError:
                report = ""  # the run is still recorded; its report is not kept
        from hil.plugin.safety import RECOVERY_NOTES
        notes = list(config.stash.get(RECOVERY_NOTES, []))

        def finish() -> None:
            self.store.finish_run(self.run_id, verdict=verdict.status if verdict else "INTERNAL ERROR",
                                  stopped=verdict.stopped if verdict else "the reporting plugin gave no verdict",
                                  not_run=verdict.not_run if verdict else 0, plc_restored=verdict.plc if verdict else "",
                                  recovery=notes, report=report or "")
        self._try(finish)
        if self.store is not None:  # None when the store and the spool both failed
            self.store.close()

    # -- helpers ------------------------------------------------------------------------------------------------------
    def _reporter(self) -> Any:
        return self.config.pluginmanager.get_plugin("hil-reporter")

    @staticmethod
    def _archive_path(reporter: Any) -> str | None:
        """Where this run's HTML report is kept once written (the next run's report links it)."""
        html = reporter.html_path
        if html is None:
            return None
        stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        bench = "".join(c if c.isalnum() or c in "._-" else "-" for c in dict(reporter.properties).get(
            "hil.bench", "bench"))
        return str((Path(html).parent / ARCHIVE / f"{stamp}-{bench}-{os.getpid()}.html").absolute())

    def _try(self, action: Any, *args: Any) -> bool:
        """Run a store action; on the first error say so once and carry on in the spool."""
        if self.store is None and self.run_id is None and action != self._open_and_start:
            return False
        try:
            action(*args)
            return True
        except Exception as exc:  # noqa: BLE001 - recording never fails a run
            return self._fail_over(exc, action, args)

    def _fail_over(self, exc: Exception, action: Any, args: tuple) -> bool:
        from hil.history.store import Store
        failed = history_config.shown(self.url)
        spool = history_config.spool_url()
        if self.spooled or self.url == spool:
            self._warn(f"history store {failed} failed ({_one_line(exc)}): the rest of this run is not recorded")
            self.store = self.run_id = None
            return False
        try:
            if self.store is not None:
                self.store.close()
            self.store, self.spooled, self.url = Store(spool), True, spool
            self.run_id = self.store.start_run(self.info)
            if action != self._open_and_start:
                action(*args)  # a test's write sends every test the store did not take
        except Exception as again:  # noqa: BLE001
            self._warn(f"history store {failed} unreachable ({_one_line(exc)}), and the local spool too "
                       f"({_one_line(again)}): this run is not recorded")
            self.store = self.run_id = None
            return False
        self._warn(f"history store {failed} unreachable ({_one_line(exc)}): this run is kept in "
                   f"{history_config.shown(spool)} — `hil history sync` uploads it")
        return True

    def _warn(self, text: str) -> None:
        if self.warned:
            return
        self.warned = True
        reporter = self.config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            reporter.ensure_newline()
            reporter.write_line(f"hil: {text}", yellow=True)
        else:
            import sys
            print(f"hil: {text}", file=sys.stderr)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text.split(" (Background on this error")[0][:300]
