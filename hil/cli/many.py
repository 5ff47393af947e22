"""``hil run --bench a.toml --bench b.toml …``: the suites against several benches at once.

One subprocess per bench (``hil run --bench X``), so each run has its own pytest session, its own emulator or
wire, and — on a real bench — holds that bench's lock (:class:`hil.core.lock.BenchLock`, taken by the plugin) for
its whole run.  Each writes ``junit-<bench>.xml`` (and ``report-<bench>.html``) beside ``--junitxml``; the
JUnit files are then merged into ``--junitxml``: one ``<testsuite>`` per bench, named after it.
"""

from __future__ import annotations

import contextlib
import re
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from rich.console import Console
from rich.table import Table
from rich.text import Text

from hil.bench.profile import check_profile, lab_request
from hil.core import signals
from hil.core.errors import HilError
from hil.core.lock import lock_key
from hil.plugin.reporting.html import write_html_sections
from hil.plugin.reporting.junit import root_name
from hil.plugin.reporting.model import records_from_json
from hil.plugin.reporting.verdict import Verdict, status_of


@dataclass
class BenchRun:
    name: str
    profile: str
    junit: Path
    log: Path
    process: subprocess.Popen | None = None
    exit: int | None = None
    wall: float = 0.0

    @property
    def records(self) -> Path:
        return self.junit.with_name(f"records-{self.name}.json")

    @property
    def traces(self) -> Path:
        return self.junit.with_name(f"traces-{self.name}")

    @property
    def html(self) -> Path:
        return self.junit.with_name(f"report-{self.name}.html")


def slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", name).strip("-") or "bench"


def plan(benches: list[str], junitxml: str, target: str | None = None) -> list[BenchRun]:
    """Load every profile first (a bad one fails before anything runs); refuse two benches that share a name
    (their reports would collide) or a PLC (their lock would make one wait for or fail against the other)."""
    out_dir = Path(junitxml).parent
    runs: list[BenchRun] = []
    names: dict[str, str] = {}
    plcs: dict[str, str] = {}
    for path in benches:
        lab = lab_request(path)  # a bench that is a labgrid place: each run reserves its own
        profile = check_profile(path, lab)
        name = slug(profile.name)
        if name in names:
            raise HilError(f"benches {names[name]} and {path} are both named {profile.name!r} — give each "
                           f"[bench] name its own value (reports are named after it)")
        names[name] = path
        url = target or profile.target
        if lab is None and not url.startswith("emulator"):  # in-process emulators are each run's own; real PLCs
            # are shared (labgrid queues runs on one place itself)
            key = lock_key(url)
            if key in plcs:
                raise HilError(f"benches {plcs[key]} and {path} both reach {key}: one PLC runs one suite at a time")
            plcs[key] = path
        runs.append(BenchRun(name, path, out_dir / f"junit-{name}.xml", out_dir / f"run-{name}.log"))
    return runs


def run_many(benches: list[str], target: str | None, junitxml: str, extra: list[str],
             console: Console | None = None, *, html: bool | str = True) -> int:
    """``html``: where the merged HTML report goes (True: report.html beside ``junitxml``; False: none)."""
    console = console or Console()
    runs = plan(benches, junitxml, target)
    out_dir = Path(junitxml).parent
    out_dir.mkdir(parents=True, exist_ok=True)
    merged = None if not html else Path(html) if isinstance(html, str) else out_dir / "report.html"
    for own in (Path(junitxml), merged):  # an earlier run's merged result must not pass for this one's
        if own is not None:
            own.unlink(missing_ok=True)
    for r in runs:
        cmd = [sys.executable, "-m", "hil.cli.main", "run", "--bench", r.profile, "--junitxml", str(r.junit)]
        if target:
            cmd += ["--target", target]
        if html:
            cmd += ["--html", str(r.html)]
        # each bench's own traces (the same test failing on two benches must not share a file) and records
        cmd += ["--", "--hil-trace-dir", str(r.traces), "--hil-records", str(r.records), *extra]
        for stale in (r.records, r.junit, r.html):  # a stale file must not pass for this run's result
            stale.unlink(missing_ok=True)
        shutil.rmtree(r.traces, ignore_errors=True)  # an earlier run's traces are not this run's evidence
        r.wall = time.perf_counter()
        with open(r.log, "wb") as log:
            r.process = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    interrupted = _wait_or_stop(console, runs)
    merge([(r.name, r.junit, r.exit, r.log) for r in runs], Path(junitxml))
    if merged is not None:
        merge_html(runs, merged)
    print_summary(console, runs, junitxml)
    if merged is not None:
        console.print(Text(f"merged HTML: {merged}"), soft_wrap=True)
    return 2 if interrupted else next((r.exit for r in runs if r.exit), 0)


def _wait_or_stop(console: Console, runs: list[BenchRun]) -> bool:
    """Wait for every bench's run; on SIGINT, SIGTERM or SIGHUP pass SIGINT on to each run still going (a run
    already stopping ignores it: hil.core.signals) and wait for each to restore its PLC and write its reports, so the
    merged ones say INTERRUPTED.  Whether the runs were stopped."""
    signals.install()
    try:
        try:
            _wait_with_counts(console, runs)
            return False
        except KeyboardInterrupt as exc:
            console.print(Text(f"hil: {exc or 'interrupted'} — stopping each bench's run; each restores its PLC and "
                               f"writes its reports first"), soft_wrap=True)
        # a second signal from here on is only reported (hil.core.signals: the run is already stopping)
        for r in runs:
            if r.process is not None and r.process.poll() is None:
                r.process.send_signal(signal.SIGINT)
        for r in runs:
            if r.exit is None and r.process is not None:
                r.exit = r.process.wait()
                r.wall = time.perf_counter() - r.wall
        return True
    finally:
        signals.uninstall()


_PROGRESS_LINE = re.compile(r"^(?:\S+\.py )?([.FEsxX]+)\s*(?:\[\s*\d+%\])?$")  # "suites/x.py ..F" or -q's "..F"


def live_counts(log: Path) -> Counter:
    """Outcomes so far, from the progress characters pytest writes to a bench's log (``suites/x.py ..F.s``)."""
    counts: Counter = Counter()
    try:
        text = log.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return counts
    names = {".": "passed", "F": "failed", "E": "error", "s": "skipped", "x": "xfailed", "X": "xpassed"}
    for line in text.splitlines():
        found = _PROGRESS_LINE.match(line)
        if found:
            counts.update(names[c] for c in found.group(1))
    return counts


def _describe(counts: Counter) -> str:
    order = ("passed", "failed", "error", "skipped", "xfailed", "xpassed")
    return ", ".join(f"{counts[k]} {k}" for k in order if counts.get(k)) or "starting"


def _wait_with_counts(console: Console, runs: list[BenchRun], every: float = 10.0) -> None:
    """Wait for every bench, with a line as each ends.  The counts so far: on a terminal one status line updated in
    place; elsewhere (a CI log) a line every ``every`` seconds."""
    pending = list(runs)
    last = time.monotonic()
    status = console.status("starting") if console.is_terminal else contextlib.nullcontext()
    with status as spinner:
        while pending:
            for r in list(pending):
                assert r.process is not None
                if r.process.poll() is not None:
                    r.exit = r.process.returncode
                    r.wall = time.perf_counter() - r.wall
                    pending.remove(r)
                    console.print(Text(f"bench {r.name}: {status_of(r.exit)} (exit {r.exit}) after {r.wall:.1f} s "
                                       f"— {_describe(live_counts(r.log))}"), soft_wrap=True)
            running = "running: " + "; ".join(f"{r.name} {_describe(live_counts(r.log))}" for r in pending)
            if spinner is not None:
                spinner.update(Text(running))
            elif pending and time.monotonic() - last >= every:
                last = time.monotonic()
                console.print(Text(running), soft_wrap=True)
            if pending:
                time.sleep(0.2)


def _records(r: BenchRun) -> tuple[list, list[tuple[str, str]]]:
    """A bench run's records and properties (none, and a property saying so, when it left no records file)."""
    try:
        return records_from_json(r.records.read_text(encoding="utf-8"))
    except (OSError, ValueError, KeyError, TypeError):
        return [], [("hil.bench", f"{r.name}: no records (exit {r.exit}; see {r.log})")]


def verdict_of(runs: list[BenchRun]) -> Verdict:
    """The benches' verdict together: PASSED when every run passed, else the gravest run's status, and what each
    run that did not pass says stopped it (its own verdict, from its records)."""
    grave = [3, 2, 1, 4, 5]  # internal error, interrupted, failed, usage error, no tests
    bad = [r for r in runs if r.exit != 0]
    if not bad:
        return Verdict("PASSED")
    worst = min(bad, key=lambda r: grave.index(r.exit) if r.exit in grave else -1)
    said = []
    for r in bad:
        props = dict(_records(r)[1])
        said.append(f"bench {r.name}: {props.get('hil.verdict') or status_of(r.exit)}"
                    + (f" ({props['hil.stopped']})" if props.get("hil.stopped") else ""))
    return Verdict(status_of(worst.exit), "; ".join(said))


def merge_html(runs: list[BenchRun], out: Path) -> Path:
    """One HTML page with a section per bench, from each run's records (a run that left none: an empty section)."""
    sections = [(r.name, *_records(r)) for r in runs]
    return write_html_sections(out, sections, title="hil test report — several benches", verdict=verdict_of(runs))


def merge(parts: list[tuple[str, Path, int | None, Path]], out: Path) -> ET.Element:
    """One ``<testsuites>`` holding each bench's ``<testsuite>`` (renamed to the bench); a bench whose run left
    no JUnit file gets a testsuite with one error naming the bench and its log."""
    root = ET.Element("testsuites", name=root_name(name for name, *_ in parts))
    totals = dict.fromkeys(("tests", "failures", "errors", "skipped"), 0)
    for name, path, exit_code, log in parts:
        suites: list[ET.Element] = []
        if path.is_file():
            try:
                top = ET.parse(path).getroot()
                suites = [top] if top.tag == "testsuite" else list(top.iter("testsuite"))
            except ET.ParseError as exc:
                suites = [_error_suite(name, f"{path} is not valid XML: {exc}; see {log}")]
        else:
            suites = [_error_suite(name, f"the run for bench {name} exited {exit_code} without a JUnit file; "
                                         f"see {log}")]
        for suite in suites:
            suite.set("name", name)
            root.append(suite)
            for key in totals:
                totals[key] += int(suite.get(key, 0) or 0)
    for key, value in totals.items():
        root.set(key, str(value))
    ET.indent(root)
    out.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(out, encoding="utf-8", xml_declaration=True)
    return root


def _error_suite(name: str, message: str) -> ET.Element:
    suite = ET.Element("testsuite", name=name, tests="1", errors="1", failures="0", skipped="0")
    case = ET.SubElement(suite, "testcase", classname=f"hil.bench.{name}", name="run")
    ET.SubElement(case, "error", message=message).text = message
    return suite


def print_summary(console: Console, runs: list[BenchRun], junitxml: str) -> None:
    """Each bench's verdict and files, then every test that failed, by name.  Paths are never cut: on a terminal
    a table folds them, elsewhere (a pipe, a CI log) each bench is one line."""
    if console.is_terminal:
        table = Table(title="hil run: benches in parallel")
        for col in ("bench", "verdict", "exit", "wall s", "JUnit", "log"):
            table.add_column(col, overflow="fold")
        for r in runs:
            style = "green" if r.exit == 0 else "red"
            table.add_row(Text(r.name), Text(status_of(r.exit), style=style), Text(str(r.exit), style=style),
                          f"{r.wall:.1f}", Text(str(r.junit)), Text(str(r.log)))
        console.print(table)
    else:
        for r in runs:
            console.print(Text(f"bench {r.name}: {status_of(r.exit)} (exit {r.exit}), {r.wall:.1f} s, JUnit "
                               f"{r.junit}, log {r.log}"), soft_wrap=True)
    failed = [(r.name, rec) for r in runs for rec in _records(r)[0] if rec.outcome.bad]
    if failed:
        console.print(Text(f"tests that did not pass ({len(failed)}):", style="bold red"), soft_wrap=True)
        for name, rec in failed:
            why = rec.message.splitlines()[-1] if rec.message else ""
            console.print(Text(f"  {name}: {rec.outcome.upper()} {rec.nodeid}" + (f" — {why}" if why else "")),
                          soft_wrap=True)
    console.print(Text(f"merged JUnit: {junitxml}"), soft_wrap=True)


__all__ = ["run_many", "merge", "plan"]
