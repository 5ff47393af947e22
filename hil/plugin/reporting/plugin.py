"""The reporting half of the hil pytest plugin (entry point ``hil-report``).

* JUnit: testsuite properties (bench, target, transport, PLC identity, RTC chip, harness version, suites commit,
  profile hash, operator, station); testcase properties for each ``measure(...)``; the wire trace of a failing
  test (every test with ``--hil-trace=all``) as its ``system-out``, also saved under ``<reports>/traces/``.
* Console: a header panel, a bar during long waits on a real bench (a terminal only), a summary table by area.
* HTML: ``--hil-html PATH`` (``hil run`` always writes reports/report.html): summary, measurements, failures,
  wire traces and plots (``report.attach_series``) in one self-contained file.
* The verdict (:mod:`hil.plugin.reporting.verdict`): pytest's exit status and what stopped the run, in the HTML
  badge, the JUnit testsuite properties and the console's last lines; while the run is under way both report
  files say INCOMPLETE, so a run that dies never leaves an earlier run's result behind.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import pytest

from hil.core.registry import REPORT_PLOTS
from hil.io.trace import WireTrace, format_trace
from hil.plugin.reporting import builtin_outputs  # noqa: F401 - registers JUnit, HTML, records and the console
from hil.plugin.reporting.console import WaitProgress
from hil.plugin.reporting.identity import suite_properties
from hil.plugin.reporting.model import Measurement, Series, TestOutcome, TestRecord, area_of
from hil.plugin.reporting.outputs import RUN, Moment, RunRecord, emit
from hil.plugin.reporting.suite_ids import show_suite_ids_from_their_root
from hil.plugin.reporting.verdict import Stops, Verdict, describe, incomplete, status_of
from hil.plugin.requirements import PROPERTY as REQUIREMENTS
from hil.plugin.safety import AS_FOUND, PLC_LEFT
from hil.plugin.usage import usage_error

TRACE_MODES = ("failures", "all", "off")


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("hil-report", "hil reports (JUnit properties, wire traces, HTML)")
    group.addoption("--operator", metavar="NAME", default=None,
                    help="who runs the tests, for the report (default $HIL_OPERATOR, else the login name)")
    group.addoption("--station", metavar="NAME", default=None,
                    help="test station, for the report (default $HIL_STATION, else the host name)")
    group.addoption("--hil-trace", choices=TRACE_MODES, default="failures",
                    help="keep wire traces for failing tests (default), all tests, or none")
    group.addoption("--hil-trace-dir", metavar="DIR", default=None,
                    help="where wire traces are saved (default: traces/ beside --junitxml or --hil-html)")
    group.addoption("--hil-html", metavar="PATH", default=None,
                    help="write a self-contained HTML report (summary, measurements, traces, plots)")
    group.addoption("--hil-records", metavar="PATH", default=None,
                    help="also save the report's records as JSON (hil run --bench a --bench b merges them)")


@pytest.hookimpl(trylast=True)
def pytest_configure(config: pytest.Config) -> None:
    show_suite_ids_from_their_root(config)
    if getattr(config, "workerinput", None) is not None:
        return  # an xdist worker: the controller reports
    plugin = Reporter(config)
    config.pluginmanager.register(plugin, "hil-reporter")


class ReportHandle:
    """What the ``report`` fixture gives a test: attach plot-ready data to its entry in the HTML report."""

    def __init__(self, record: TestRecord, node: pytest.Item | None = None, directory: Path | None = None) -> None:
        self._record = record
        self._node = node
        self._directory = directory

    def attach_file(self, name: str, content: str | bytes) -> Path | None:
        """Save ``content`` as a file beside the reports (``attachments/<test>-<name>``): the test's JUnit record
        gets a ``hil.attachment.<name>`` property with its path, the HTML report a link.  A CSV of 140 rows is a
        file, not a property.  Returns the path (None when no report is being written)."""
        if not re.fullmatch(r"[A-Za-z0-9_.\-]+", name):
            raise ValueError(f"attachment name {name!r}: use letters, digits, _ . - (it becomes a file name)")
        if self._directory is None:
            return None
        self._directory.mkdir(parents=True, exist_ok=True)
        path = self._directory / f"{_safe_name(self._record.nodeid)}-{name}"
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
        self._record.attachments.append(str(path))
        if self._node is not None:
            self._node.user_properties.append((f"hil.attachment.{name}", str(path)))
        return path

    def attach_series(self, name: str, data: Mapping[str, Sequence[float]] | Sequence[Sequence[float]], *,
                      columns: Sequence[str] | None = None, x: str | None = None, title: str = "",
                      xlabel: str = "", ylabel: str = "", secondary: Sequence[str] = (),
                      secondary_label: str = "") -> Series:
        """Columns (``{"t": [...], "PV": [...]}``) or rows with ``columns=("t", "PV", "SV", "output")``; ``x``
        names the horizontal axis (default the first column); ``secondary`` columns get a right-hand axis."""
        series = Series.build(name, data, columns=columns, x=x, title=title, xlabel=xlabel, ylabel=ylabel,
                              secondary=secondary, secondary_label=secondary_label)
        self._record.series.append(series)
        return series

    def __getattr__(self, name: str) -> Callable[..., Series]:
        """``attach_<plot>``: a plot a family registered (:data:`hil.core.registry.REPORT_PLOTS`), e.g. a clock's
        drift or a closed loop's trace, drawn through :meth:`attach_series`."""
        plot = REPORT_PLOTS.get(name.removeprefix("attach_")) if name.startswith("attach_") else None
        if plot is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        return lambda *args, **kwargs: plot(self, *args, **kwargs)


class Reporter:
    """Per-session: one record per test (the run's record, :data:`~hil.plugin.reporting.outputs.RUN`), the suite
    properties, the wire trace recorder; the registered outputs are called at each moment of the run."""

    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.run = config.stash[RUN] = RunRecord(config, html_path=_path(config.getoption("--hil-html")))
        self.current = ""
        self.trace_mode: str = config.getoption("--hil-trace")
        self.trace: WireTrace | None = None  # once a bench is open
        self._traced_bench: Any = None
        self.trace_dir = self._trace_dir()
        if self.trace_dir is not None:
            self.run.attachments_dir = self.attachments_dir
        self.stops = Stops(config)  # the report of a test the run stopped in, and what stopped it
        config.pluginmanager.register(self.stops, "hil-stops")
        state = self.run.state
        if state is not None:
            state.header_panel = True  # the console output's panel replaces the plugin's "hil PLC: …" line

    @property
    def records(self) -> dict[str, TestRecord]:
        return self.run.records

    def _trace_dir(self) -> Path | None:
        given = _path(self.config.getoption("--hil-trace-dir"))
        if given is not None:
            return given
        for base in (self.run.xmlpath, self.run.html_path):
            if base is not None:
                return base.parent / "traces"
        return None

    def pytest_sessionstart(self, session: pytest.Session) -> None:
        """Traces and attachments beside a report belong to that report: drop the previous run's (an explicit
        directory is left alone)."""
        if self.trace_dir is not None and self.config.getoption("--hil-trace-dir") is None:
            for old in [*self.trace_dir.glob("*.txt"), *self.attachments_dir.glob("*")]:
                with contextlib.suppress(OSError):
                    old.unlink()

    @property
    def attachments_dir(self) -> Path:
        assert self.trace_dir is not None
        return self.trace_dir.parent / "attachments"

    # -- collection: properties and the header ----------------------------------------------------------------
    @pytest.hookimpl(trylast=True)
    def pytest_collection_finish(self, session: pytest.Session) -> None:
        items = [i for i in session.items if "bench" in getattr(i, "fixturenames", ())]
        self._collected(Path(str(items[0].path)).parent if items else None)

    @pytest.hookimpl(optionalhook=True)
    def pytest_xdist_node_collection_finished(self, node: Any, ids: list[str]) -> None:
        """A pytest-xdist controller collects nothing itself: its first worker's collection stands for the run's
        (a run with lanes, hil.plugin.lanes: every worker collects every test).  The PLC's identity is not in the
        header here — the controller let go of the wire for its workers."""
        if self.run.verdict is not None or not ids:
            return
        self._collected((self.config.rootpath / ids[0].split("::")[0]).parent)

    def _collected(self, suites: Path | None) -> None:
        """The bench tests are known (``suites``: their directory; None: no test uses the bench)."""
        self.run.uses_bench = suites is not None
        state = self.run.state
        if suites is None or state is None:
            return
        try:
            self.run.properties = suite_properties(
                profile=state.profile, target=state.target, bench=state.bench, bench_error=state.error,
                suites=suites, operator=self.config.getoption("--operator"),
                station=self.config.getoption("--station"))
        except Exception as exc:  # noqa: BLE001 - the report says what it could not find; tests still run
            self.run.properties = [("hil.properties", f"unavailable: {exc}")]
        self._attach(state)
        self.run.verdict = incomplete(dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M:%S %Z"))
        try:
            emit(Moment.STARTED, self.run)  # the report files say INCOMPLETE until the session's end replaces them
        except OSError as exc:
            raise usage_error(f"cannot write the reports: {exc}") from None

    def _attach(self, state: Any) -> None:
        """Hook the trace recorder (and, on a real bench's terminal, the wait bar) into the open bench."""
        bench = getattr(state, "bench", None)
        if bench is None or bench is self._traced_bench:
            return
        self._traced_bench = bench
        if self.trace_mode != "off":
            self.trace = WireTrace().attach(bench.raw)
        timebase = getattr(bench, "time", None)
        add_listener = getattr(timebase, "add_wait_listener", None)  # a real bench's host time (public callback)
        if add_listener is not None and self.config.get_verbosity() >= 0:
            capman = self.config.pluginmanager.get_plugin("capturemanager")
            suspend = capman.global_and_fixture_disabled if capman is not None else contextlib.nullcontext
            add_listener(WaitProgress(current=lambda: self.current, suspend=suspend))

    # -- per test ------------------------------------------------------------------------------------------------
    def pytest_runtest_logstart(self, nodeid: str, location: tuple) -> None:
        self.current = nodeid
        self.records[nodeid] = TestRecord(nodeid, area_of(nodeid))
        state = self.run.state
        if state is not None:
            self._attach(state)
        if self.trace is not None:
            self.trace.start()

    @pytest.hookimpl(tryfirst=True)
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        record = self.run.record(report.nodeid, area_of(report.nodeid))
        record.duration += getattr(report, "duration", 0.0)
        _outcome(record, report, aborted=self.stops.aborted(report))
        ids = next((v for k, v in report.user_properties if k == REQUIREMENTS), None)
        if ids is not None:  # the IDs of its spec() marker: the HTML requirement table is built from them
            record.requirements = str(ids).split()
        category = self.config.hook.pytest_report_teststatus(report=report, config=self.config)[0]
        if category:  # what pytest's summary counts this report as ("" for a passed setup or teardown)
            record.counted[category] = record.counted.get(category, 0) + 1
        if report.when == "teardown":
            self._finish(record, report)

    def _finish(self, record: TestRecord, report: pytest.TestReport) -> None:
        if self.trace is None:
            return
        entries = self.trace.stop()
        keep = entries and (self.trace_mode == "all" or record.outcome.bad)
        if not keep:
            return
        record.trace = format_trace(entries, dropped=self.trace.dropped, kind=self.trace.kind)
        if self.trace_dir is not None:
            try:
                self.trace_dir.mkdir(parents=True, exist_ok=True)
                path = self.trace_dir / (_safe_name(record.nodeid) + ".txt")
                path.write_text(f"# {record.nodeid}: {record.outcome}\n" + record.trace, encoding="utf-8")
                record.trace_file = str(path)
            except OSError as exc:
                record.trace_file = f"not saved: {exc}"
        # The testcase's property (pytest's public user_properties, read by --junitxml after this hook); the trace
        # itself goes into its system-out when the JUnit file is finished (the JUnit output, Moment.CLOSED)
        key = record.trace_file or f"{record.nodeid} (not saved)"
        report.user_properties.append(("hil.trace_file", key))
        self.run.junit_traces[key] = record.trace

    # -- the end ---------------------------------------------------------------------------------------------------
    @pytest.hookimpl(wrapper=True, tryfirst=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> Any:
        """Around everything else at the session's end (the last restores, pytest's JUnit file, its summary): then
        the verdict, from the session's final exit status, to every output."""
        failure: BaseException | None = None
        try:
            return (yield)
        except KeyboardInterrupt as exc:  # a signal during the last restores, raised once they finished
            failure = exc
            session.exitstatus = pytest.ExitCode.INTERRUPTED
            return None  # the run ends here anyway; pytest still unconfigures (the JUnit file gets the verdict)
        except BaseException as exc:  # a teardown at the session's end raised: pytest stops here
            failure = exc
            raise
        finally:
            self.run.verdict = self._verdict(session, failure)
            self.run.after_progress = failure is not None  # then pytest's summary did not end the line
            emit(Moment.FINISHED, self.run)

    def _verdict(self, session: pytest.Session, failure: BaseException | None) -> Verdict:
        stopped = self.stops.stopped
        if failure is not None:
            stopped = stopped or f"{describe(failure)} at the end of the session"
        elif not stopped and (session.shouldfail or session.shouldstop):
            reason = session.shouldfail or session.shouldstop
            stopped = reason if isinstance(reason, str) else "stopped early"
        status = status_of(3 if failure is not None and not isinstance(failure, KeyboardInterrupt)
                           else session.exitstatus)
        plc = self.config.stash.get(PLC_LEFT, "")
        if plc == AS_FOUND and not stopped:
            plc = ""  # said only when the run was stopped, or left something changed
        return Verdict(status, stopped, self.stops.not_run(session.items) if stopped else 0, plc)

    @pytest.hookimpl(trylast=True)
    def pytest_unconfigure(self, config: pytest.Config) -> None:
        """After --junitxml wrote its file (pytest_sessionfinish)."""
        emit(Moment.CLOSED, self.run)

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        emit(Moment.SUMMARY, self.run)


# -- fixtures ---------------------------------------------------------------------------------------------------------
_NODE_RECORD = pytest.StashKey[TestRecord]()


def _record(request: pytest.FixtureRequest) -> TestRecord:
    return _record_of(request.node)


def _record_of(item: pytest.Item) -> TestRecord:
    run = item.config.stash.get(RUN, None)
    nodeid = item.nodeid
    if run is None:  # an xdist worker or the plugin disabled: keep the data on the node
        return item.stash.setdefault(_NODE_RECORD, TestRecord(nodeid, area_of(nodeid)))
    return run.record(nodeid, area_of(nodeid))


def _check_name(name: str) -> None:
    if not re.fullmatch(r"[A-Za-z0-9_.\-]+", name):
        raise ValueError(f"measurement name {name!r}: use letters, digits, _ . - (it becomes a JUnit property)")


@pytest.fixture
def measure(request: pytest.FixtureRequest) -> Callable[..., Measurement]:
    """Record a measurement — ``measure("drift", 0.03, unit="s/day", low=-0.088, high=0.088)`` — as JUnit
    testcase properties and in the HTML report; fail the test at once when it is outside its limits.

    ``note``: context added to the failure message (what an out-of-limits value usually means).  Limits are declared
    once: a measurement its test declares (``@pytest.mark.measures``) takes its unit and limits from there, and a
    call that gives one the declaration gave too is refused (two statements of a limit could differ)."""
    record = _record(request)

    def measure(name: str, value: float, *, unit: str = "", low: float | None = None,
                high: float | None = None, note: str = "") -> Measurement:
        _check_name(name)
        declared = next((m for m in record.measurements if m.name == name and m.value is None), None)
        if declared is not None:
            given = {"unit": unit or None, "low": low, "high": high}
            twice = [k for k, v in given.items() if v is not None and getattr(declared, k) not in (None, "")]
            if twice:
                raise ValueError(f"measurement {name!r}: {', '.join(twice)} declared by @pytest.mark.measures "
                                 f"already; give each limit once (there, or in the call when the declaration "
                                 f"leaves it out)")
            unit = unit or declared.unit
            low = declared.low if low is None else low
            high = declared.high if high is None else high
            record.measurements.remove(declared)
        m = Measurement(name, float(value), unit, None if low is None else float(low),
                        None if high is None else float(high))
        record.measurements.append(m)
        request.node.user_properties.extend(m.properties())
        if not m.passed:
            pytest.fail(f"measurement {m.describe()}" + (f": {note}" if note else ""), pytrace=False)
        return m

    return measure


@pytest.fixture
def report(request: pytest.FixtureRequest) -> ReportHandle:
    """Attach plot-ready series to this test's entry in the HTML report (``report.attach_series(...)``)."""
    run = request.config.stash.get(RUN, None)
    directory = run.attachments_dir if run is not None else None
    return ReportHandle(_record(request), request.node, directory)


def pytest_runtest_setup(item: pytest.Item) -> None:
    """Declared measurements (``@pytest.mark.measures(...)``) enter the record UNSET before the test runs."""
    markers = list(item.iter_markers("measures"))
    if not markers:
        return
    record = _record_of(item)
    for marker in markers:
        if len(marker.args) != 1 or not isinstance(marker.args[0], str):
            raise usage_error(f"{item.nodeid}: measures() takes the measurement's name, then unit=, low=, "
                              f"high= (got {marker.args!r})")
        name = marker.args[0]
        _check_name(name)
        low, high = marker.kwargs.get("low"), marker.kwargs.get("high")
        if all(m.name != name for m in record.measurements):
            record.measurements.append(Measurement(name, None, marker.kwargs.get("unit", ""),
                                                   None if low is None else float(low),
                                                   None if high is None else float(high)))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Any:
    """A test that passes while a measurement it declared is still UNSET has not shown its evidence: it fails."""
    outcome = yield
    report = outcome.get_result()
    if call.when != "call" or not report.passed or not any(True for _ in item.iter_markers("measures")):
        return
    unset = [m for m in _record_of(item).measurements if m.value is None]
    if unset:
        report.outcome = "failed"
        report.longrepr = (f"declared measurement(s) never measured: {', '.join(m.describe() for m in unset)} — "
                           f"a test passes only with its evidence")
    for m in unset:
        item.user_properties.extend(m.properties())


def pytest_make_parametrize_id(config: pytest.Config, val: object, argname: str) -> str | None:
    """Bytes parameters (an S7 clock buffer) as hex, ``24.06.15.08.30.00.00.07``, not escaped raw bytes."""
    if isinstance(val, (bytes, bytearray)):
        return val.hex(".").upper()
    return None


# -- helpers ---------------------------------------------------------------------------------------------------------
def _path(value: Any) -> Path | None:
    return Path(value) if value else None


def _safe_name(nodeid: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.\-]+", "_", nodeid).strip("_")[:180]


def _outcome(record: TestRecord, report: pytest.TestReport, *, aborted: bool = False) -> None:
    """What ``report`` shows of its test, never more: a pass only from a passing call, ABORTED for the report
    :class:`~hil.plugin.reporting.verdict.Stops` gave a test the run stopped inside (unless it had failed already:
    that was shown)."""
    if report.passed:
        if report.when == "call" and record.outcome is TestOutcome.INCOMPLETE:
            record.outcome = TestOutcome.PASS
        return
    if report.skipped:
        if record.outcome in (TestOutcome.INCOMPLETE, TestOutcome.PASS):
            _skipped(record, report)
        return
    _failed(record, report, aborted=aborted)


def _skipped(record: TestRecord, report: pytest.TestReport) -> None:
    """A skip, or an expected failure (xfail), as pytest counts them, with its reason."""
    reason = getattr(report, "wasxfail", None)
    record.outcome = TestOutcome.SKIP if reason is None else TestOutcome.XFAIL
    if reason is not None:
        record.message = f"xfail: {reason}" if reason else "xfail"
    elif isinstance(report.longrepr, tuple) and len(report.longrepr) == 3:
        record.message = str(report.longrepr[2]).removeprefix("Skipped: ")
    else:
        record.message = str(report.longrepr or "")


def _failed(record: TestRecord, report: pytest.TestReport, *, aborted: bool) -> None:
    """A failed phase: the call's failure, a setup's or teardown's error, or the run stopping inside the test —
    never hiding a failure already shown; its message and text added to the record's."""
    crash = getattr(getattr(report, "longrepr", None), "reprcrash", None)
    text = report.longreprtext.strip()
    message = crash.message if crash is not None else (text.splitlines()[-1] if text else "failed")
    if aborted:
        if record.outcome not in (TestOutcome.FAIL, TestOutcome.ERROR):
            record.outcome = TestOutcome.ABORTED
    elif report.when == "call":
        record.outcome = TestOutcome.FAIL
    elif record.outcome not in (TestOutcome.FAIL, TestOutcome.ABORTED):
        record.outcome = TestOutcome.ERROR
    line = f"{report.when}: {message}"
    record.message = f"{record.message}\n{line}" if record.message else line
    record.longrepr = f"{record.longrepr}\n\n{report.longreprtext}" if record.longrepr else report.longreprtext
