"""The pytest plugin that records each session in the history (entry point ``hil-history``).

It reads what the reporting plugin (``hil-reporter``) already holds — the testsuite properties, each test's
record with its measurements, the verdict — and writes it as the run goes: the run when its tests start, each test
after its teardown, the verdict at the end.  Before the HTML report is written it gives the reporter the bench's
history (:mod:`hil.history.annotate`).

The store is written by a process of its own (:mod:`hil.history.writer`, fed JSON lines), so this one never
imports SQLAlchemy nor waits for a database.  Recording never fails a run: the first error of the store is reported
once (one line), and the rest of the run — its row and its tests so far included — goes to the local spool, which
``hil history sync`` uploads later.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import os
import queue
import socket
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path
from typing import Any

import pytest

from hil.core import signals
from hil.history import config as history_config
from hil.history.annotate import Annotations
from hil.plugin.reporting.outputs import RUN, RunRecord
from hil.plugin.safety import RECOVERY_NOTES

#: seconds to wait for the writer's answer (the bench's history) and for its end (as the store waits for a lock)
WAIT_S = 5.0

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
        self.writer: subprocess.Popen | None = None  # hil.history.writer, while recording
        self.bench = ""
        self.report: str | None = None  # where this run's HTML report is kept
        self.attempts: dict[str, int] = {}
        self.said = False
        self._replies: queue.Queue = queue.Queue()  # what the writer said, read by a thread
        self._pending: list[dict] = []  # said while an answer was awaited

    # -- the start ----------------------------------------------------------------------------------------------
    @pytest.hookimpl(tryfirst=True)
    def pytest_runtestloop(self, session: pytest.Session) -> None:
        reporter = self._reporter()
        if reporter is None or not reporter.uses_bench or self.config.option.collectonly:
            return
        state = reporter.state
        profile = getattr(state, "profile", None)
        try:
            url = history_config.resolve(self.config.getoption("--hil-history"),
                                         getattr(profile, "history_url", None))
        except Exception as exc:  # noqa: BLE001 - a bad URL is said once; the run goes on
            self._warn(f"history off: {exc}")
            return
        if url is None:
            return
        self.bench = dict(reporter.properties).get("hil.bench") or getattr(profile, "name", "") or "bench"
        self.report = self._archive_path(reporter)
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}  # this process's hil
        try:
            # A session of its own: a Ctrl-C (SIGINT to the terminal's foreground group) or a closed terminal
            # (SIGHUP) stops the run, not its recording — the writer ends when its input does, once the run's end
            # (or its process's death) has been written.
            self.writer = subprocess.Popen([sys.executable, "-m", "hil.history.writer"], stdin=subprocess.PIPE,
                                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env, text=True,
                                           encoding="utf-8", bufsize=1, start_new_session=True)
        except OSError as exc:
            self._warn(f"history off: cannot start its writer ({exc})")
            return
        threading.Thread(target=self._read_replies, args=(self.writer.stdout,), daemon=True).start()
        info = {"bench": self.bench, "properties": list(reporter.properties),
                "started_at": dt.datetime.now(dt.UTC).replace(tzinfo=None).isoformat(), "uuid": str(uuid.uuid4()),
                "host": socket.gethostname(), "pid": os.getpid(), "report": self.report}
        self._send({"op": "start", "url": url, "info": info})

    # -- each test ----------------------------------------------------------------------------------------------
    @pytest.hookimpl(trylast=True)  # after the reporter has taken the teardown's report into its record
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if report.when != "teardown" or self.writer is None:
            return
        reporter = self._reporter()
        record = reporter.records.get(report.nodeid) if reporter is not None else None
        if record is None:
            return
        self.attempts[report.nodeid] = attempt = self.attempts.get(report.nodeid, 0) + 1
        skip = ("hil.measure.", "hil.trace_file", "hil.attachment.")
        extra = {str(k): v for k, v in report.user_properties if not str(k).startswith(skip)}
        self._send({"op": "test", "result": {
            "nodeid": record.nodeid, "outcome": record.outcome, "area": record.area, "duration": record.duration,
            "attempt": attempt, "requirements": list(record.requirements), "message": record.message,
            "properties": extra, "measurements": [dataclasses.asdict(m) for m in record.measurements]}})
        self._say_warnings()

    # -- the end ------------------------------------------------------------------------------------------------------
    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        """Inside the reporter's wrapper, before it writes the HTML report: the bench's history for that report."""
        reporter = self._reporter()
        if reporter is None or self.writer is None:
            return
        self._send({"op": "history", "bench": self.bench, "n": SPARK_RUNS})
        answer = self._reply("history", 2 * WAIT_S + 5)  # behind a write waiting out a lock, and the fail-over
        self._say_warnings()
        if answer is None:
            return
        last, values = answer["history"]["last"], answer["history"]["values"]
        for row in ([last] if last else []) + values:
            row["started_at"] = dt.datetime.fromisoformat(row["started_at"])
        reporter.annotations = Annotations.build(last, values, reporter.records.values(), html=reporter.html_path,
                                                 store=answer["store"], spooled=answer["spooled"])

    @pytest.hookimpl(tryfirst=True)  # before the other plugins' ends: a Ctrl-C in one of those skips the rest
    def pytest_unconfigure(self, config: pytest.Config) -> None:
        if self.writer is None:
            return
        interrupted = False
        try:
            with signals.shielded():  # the verdict is known: a Ctrl-C now waits until the run's end is sent
                self._send_the_end(config)
        except KeyboardInterrupt:
            interrupted = True  # held back until the end was sent: it stops only the wait for the writer
        self._end_writer(wait=not interrupted)
        self._say_warnings()

    def _send_the_end(self, config: pytest.Config) -> None:
        """The verdict and where this run's HTML report is kept (copied beside the earlier runs')."""
        reporter = self._reporter()
        verdict = getattr(reporter, "verdict", None)
        report = self.report
        written = getattr(reporter, "html_written", None)
        if report and written is not None:
            try:
                Path(report).parent.mkdir(parents=True, exist_ok=True)
                page = Path(written).read_text(encoding="utf-8")
                # the copy sits beside the earlier ones: its link to the previous report is relative to there
                Path(report).write_text(page.replace(f'href="{ARCHIVE}/', 'href="'), encoding="utf-8")
            except OSError:
                report = ""  # the run is still recorded; its report is not kept
        else:
            report = ""
        self._send({"op": "finish", "verdict": verdict.status if verdict else "INTERNAL ERROR",
                    "stopped": verdict.stopped if verdict else "the reporting plugin gave no verdict",
                    "not_run": verdict.not_run if verdict else 0, "plc_restored": verdict.plc if verdict else "",
                    "recovery": _recovery_notes(config), "report": report})

    def _end_writer(self, wait: bool = True) -> None:
        """Close the writer's input and (``wait``) wait for the run's end to be in the store before this process
        ends; a store slower than that, or a Ctrl-C meanwhile, stops only the wait (the writer finishes on its own,
        in a session of its own)."""
        writer, self.writer = self.writer, None
        if writer is None:  # it stopped while the run's end was sent: said once already
            return
        try:
            assert writer.stdin is not None
            writer.stdin.close()
            if wait:
                writer.wait(timeout=2 * WAIT_S + 5)
        except (OSError, subprocess.TimeoutExpired):
            pass
        except KeyboardInterrupt:
            self._warn("history: interrupted while its writer finished: it finishes on its own")

    # -- helpers ------------------------------------------------------------------------------------------------------
    def _send(self, message: dict) -> None:
        try:
            assert self.writer is not None and self.writer.stdin is not None
            self.writer.stdin.write(json.dumps(message, default=str) + "\n")
        except (OSError, ValueError) as exc:  # the writer died: said once, the run goes on
            self._warn(f"history: its writer stopped ({exc}); the rest of this run is not recorded")
            self.writer = None

    def _read_replies(self, stream: Any) -> None:
        for line in stream:
            try:
                self._replies.put(json.loads(line))
            except ValueError:
                continue

    def _reply(self, key: str, timeout: float) -> dict | None:
        """The writer's answer with ``key``; its warnings meanwhile are kept for :meth:`_say_warnings`."""
        deadline = time.monotonic() + timeout
        while (left := deadline - time.monotonic()) > 0:
            try:
                message = self._replies.get(timeout=left)
            except queue.Empty:
                break
            if key in message:
                return message
            self._pending.append(message)
        return None

    def _say_warnings(self) -> None:
        messages = list(self._pending)
        self._pending = []
        while True:
            try:
                messages.append(self._replies.get_nowait())
            except queue.Empty:
                break
        for message in messages:
            if "warn" in message:
                self._warn(message["warn"])

    def _reporter(self) -> RunRecord | None:
        """The run's record (the reporter's), where it writes the reports from."""
        return self.config.stash.get(RUN, None)

    @staticmethod
    def _archive_path(reporter: RunRecord) -> str | None:
        """Where this run's HTML report is kept once written (the next run's report links it)."""
        html = reporter.html_path
        if html is None:
            return None
        stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        bench = "".join(c if c.isalnum() or c in "._-" else "-" for c in dict(reporter.properties).get(
            "hil.bench", "bench"))
        return str((Path(html).parent / ARCHIVE / f"{stamp}-{bench}-{os.getpid()}.html").absolute())

    def _warn(self, text: str) -> None:
        if self.said:
            return
        self.said = True
        reporter = self.config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            reporter.ensure_newline()
            reporter.write_line(f"hil: {text}", yellow=True)
        else:
            print(f"hil: {text}", file=sys.stderr)


def _recovery_notes(config: pytest.Config) -> list[str]:
    """What the safety plugin's recovery said during the run (nothing when it had nothing to replay)."""
    notes: list[str] = config.stash.get(RECOVERY_NOTES, [])
    return list(notes)
