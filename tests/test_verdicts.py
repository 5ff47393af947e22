"""Verdicts that cannot lie (issue 24): a run that was interrupted (SIGINT, SIGTERM), timed out (pytest-timeout) or
crashed (an internal error mid-session) says so on the console, in the HTML badge and in JUnit, with the counts
pytest itself gives.  Each run is a real pytest process on a tiny suite against the in-process emulator, sent real
signals; pytest's own terminal counts are compared with the JUnit file (read with junitparser)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest
from junitparser import Error, Failure, JUnitXml, Skipped

from tests import processes
from tests.conftest import EMULATOR_BENCH

TINY = '''
import time
import pytest

def test_first(bench):
    pass

def test_writes_then_waits(bench):
    bench.plc.io.write("R1000", 4242)
    print("waiting", flush=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # a signal lands inside hil's code, below this test
        bench.plc.io.read("R1000")

def test_never_runs(bench):
    pass
'''


def run_tiny(tmp_path: Path, source: str, *args: str, signal_after: str | None = None, sig: int = 0,
             conftest: str = "", target: str = "emulator") -> tuple[subprocess.CompletedProcess, Path]:
    """pytest on ``source`` as the only test file of a fresh directory; with ``signal_after`` the signal ``sig`` is
    sent once that line is printed.  Returns the finished process (stdout and stderr together) and the output dir."""
    suite = tmp_path / "suite"
    suite.mkdir(exist_ok=True)
    (suite / "test_tiny.py").write_text(source)
    if conftest:
        (suite / "conftest.py").write_text(conftest)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "pytest", str(suite), "-s", "--rootdir", str(suite), "-p", "no:cacheprovider",
           "-p", "no:hypothesispytest", "--assert=plain", "--bench", str(EMULATOR_BENCH), "--target", target,
           f"--junitxml={out / 'junit.xml'}", "-o", "junit_family=xunit1", "--hil-html", str(out / "report.html"),
           *args]
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "PY_COLORS")}
    child = processes.spawn(cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    seen: list[str] = []
    if signal_after is not None:
        assert child.stdout is not None
        for line in child.stdout:
            seen.append(line)
            if signal_after in line:
                child.send_signal(sig)
                break
    rest, _ = child.communicate(timeout=60)
    return subprocess.CompletedProcess(cmd, child.returncode, "".join(seen) + rest), out


def pytest_counts(stdout: str) -> Counter:
    """pytest's own counts, from its last summary line (``== 1 failed, 2 passed in 3.1s ==``)."""
    line = [ln for ln in stdout.splitlines() if re.search(r"\b\d+ (passed|failed|errors?|skipped)\b.* in [\d.]+s", ln)]
    assert line, stdout
    counts = Counter()
    for n, what in re.findall(r"(\d+) (passed|failed|errors?|skipped|xfailed|xpassed)", line[-1]):
        counts["error" if what.startswith("error") else what] += int(n)
    return counts


def junit_counts(path: Path) -> tuple[Counter, dict[str, str], list]:
    """Per-testcase outcomes (pytest's own "internal error" testcase apart), the testsuite properties, the cases."""
    suite = next(iter(JUnitXml.fromfile(str(path))))
    counts, cases = Counter(), []
    for case in suite:
        if (case.classname, case.name) == ("pytest", "internal"):
            continue
        cases.append(case)
        if not case.result:
            counts["passed"] += 1
        for result in case.result:  # as pytest counts: a failed call and a failed teardown are one of each
            counts[{Failure: "failed", Error: "error", Skipped: "skipped"}[type(result)]] += 1
    assert suite.failures == counts["failed"] and suite.skipped == counts["skipped"], (suite.failures, counts)
    return counts, {p.name: p.value for p in suite.properties()}, cases


def html_badge(path: Path) -> str:
    return re.search(r'<h1>.*?<span class="badge \w+">([^<]+)</span>', path.read_text(encoding="utf-8")).group(1)


def check_stopped(proc: subprocess.CompletedProcess, out: Path, status: str, what: str) -> dict[str, str]:
    """The verdict everywhere: console, HTML badge, JUnit (counts equal to pytest's, a property naming the stop)."""
    counts, props, cases = junit_counts(out / "junit.xml")
    assert counts == pytest_counts(proc.stdout), proc.stdout
    assert all(case.name for case in cases), "no nameless <testcase/>"
    assert props["hil.verdict"] == status and what in props["hil.stopped"], props
    assert html_badge(out / "report.html") == status
    lines = proc.stdout.rstrip().splitlines()
    verdict = next(ln for ln in lines if ln.startswith("hil: ") and status in ln)
    assert what in verdict, verdict
    assert lines[-1].startswith("hil: reports ") and str(out / "junit.xml") in lines[-1], lines[-3:]
    assert "hil/core/signals.py" not in proc.stdout
    if status == "INTERRUPTED":  # pytest's "<file>:<line>: KeyboardInterrupt" names the test's line, not hil's
        assert re.search(r"^\S*test_tiny\.py:\d+: KeyboardInterrupt", proc.stdout, re.M), proc.stdout
    return props


@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_signal_mid_test_says_interrupted_everywhere(tmp_path, signame):
    proc, out = run_tiny(tmp_path, TINY, signal_after="waiting", sig=getattr(signal, signame))
    assert proc.returncode == 2, proc.stdout
    props = check_stopped(proc, out, "INTERRUPTED", f"{signame} received during test_tiny.py::test_writes_then_waits")
    counts, _, cases = junit_counts(out / "junit.xml")
    assert counts == Counter(passed=1, failed=1)  # the interrupted test is not listed as passed
    failed = next(c for c in cases if c.result)
    assert failed.name == "test_writes_then_waits" and "did not finish" in failed.result[0].message
    assert props["hil.not_run"] == "1"  # test_never_runs
    # the PLC: restored by the bench fixture's teardown, and said so
    assert props["hil.plc_restored"].startswith("the PLC is as it was found"), props
    assert "the PLC is as it was found" in proc.stdout
    page = (out / "report.html").read_text(encoding="utf-8")
    # the interrupted test has no result: ABORTED, not failed (pytest counts it as a failure, and so do the counts)
    assert re.search(r'badge aborted">aborted</span> test_<wbr>', page) and "1 passed, 1 failed" in page


PLC_GOES_AWAY = '''
import pytest
from hil.core.errors import TransportError
from hil.plugin.pytest_plugin import BENCH_SESSION


@pytest.fixture(autouse=True)
def plc_goes_away(request, bench):
    """Torn down before the bench: from then on the PLC answers nothing, so the stopped test's restore fails."""
    yield
    if request.node.name != "test_writes_then_waits":
        return
    raw = request.config.stash[BENCH_SESSION].bench.raw

    def gone(*args, **kwargs):
        raise TransportError("the PLC went away")
    for name in ("write_many", "write_words", "write_bits", "write", "read_many", "read_words", "read_bits", "read"):
        setattr(raw, name, gone)
'''


def test_an_interrupt_whose_restore_fails_says_the_plc_is_not_as_found(tmp_path):
    proc, out = run_tiny(tmp_path, TINY, signal_after="waiting", sig=signal.SIGINT, conftest=PLC_GOES_AWAY)
    assert proc.returncode == 2, proc.stdout
    props = check_stopped(proc, out, "INTERRUPTED", "SIGINT received during test_tiny.py::test_writes_then_waits")
    counts, _, cases = junit_counts(out / "junit.xml")
    assert counts == Counter(passed=1, failed=1, error=1)  # the stopped call, and its restore (the teardown)
    # pytest's JUnit gives a failed call and a failed teardown a testcase each
    said = [r.message or "" for c in cases if c.name == "test_writes_then_waits" for r in c.result]
    assert len(said) == 2 and "did not finish" in said[0] and "RestoreError" in said[1], said
    assert props["hil.plc_restored"] == "the PLC is NOT as it was found: 1 element still changed"
    # the HTML and the console's table count as pytest does: one failure and one error for that test
    assert "2 tests · 1 passed, 1 failed, 1 error, 0 skipped" in (out / "report.html").read_text(encoding="utf-8")
    all_row = next(line for line in proc.stdout.splitlines() if line.startswith("| all"))
    assert re.findall(r"\d+", all_row) == ["1", "1", "1", "0"], all_row  # passed failed error skipped
    assert "the PLC is NOT as it was found" in proc.stdout.splitlines()[-2]


def test_a_pytest_timeout_fails_the_test_and_the_run(tmp_path):
    source = TINY.replace("def test_writes_then_waits", "@pytest.mark.timeout(1)\ndef test_writes_then_waits")
    proc, out = run_tiny(tmp_path, source)
    assert proc.returncode == 1, proc.stdout
    counts, props, cases = junit_counts(out / "junit.xml")
    assert counts == pytest_counts(proc.stdout) == Counter(passed=2, failed=1)
    timed_out = next(c for c in cases if c.result)
    assert timed_out.name == "test_writes_then_waits" and "Timeout" in timed_out.result[0].message
    assert props["hil.verdict"] == "FAILED" and html_badge(out / "report.html") == "FAILED"
    assert "hil: FAILED" in proc.stdout


def test_a_pytest_session_timeout_says_what_stopped_the_run(tmp_path):
    """pytest-timeout's --session-timeout ends the run between tests: every test that ran passed, yet the run is
    FAILED (pytest's exit status 1) and says why, and how many tests never ran."""
    source = "import time\n" + "".join(f"def test_{i}(bench):\n    time.sleep(0.6)\n" for i in range(5))
    proc, out = run_tiny(tmp_path, source, "--session-timeout", "1.5")  # expires by the third test's end
    assert proc.returncode == 1, proc.stdout
    props = check_stopped(proc, out, "FAILED", "session-timeout: 1.5 sec exceeded")
    counts = junit_counts(out / "junit.xml")[0]
    assert set(counts) == {"passed"} and int(props["hil.not_run"]) == 5 - counts["passed"] >= 2, (counts, props)


def test_a_run_killed_by_pytest_timeouts_thread_method_leaves_no_earlier_result(tmp_path):
    """The thread method ends the process (os._exit): the reports this run began say it never finished."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "junit.xml").write_text('<testsuites><testsuite name="old" tests="1" errors="0" failures="0">'
                                   '<testcase classname="x" name="earlier_pass"/></testsuite></testsuites>')
    source = TINY.replace("def test_writes_then_waits", '@pytest.mark.timeout(1, method="thread")\n'
                                                        'def test_writes_then_waits')
    proc, out = run_tiny(tmp_path, source)
    assert proc.returncode == 1 and "Timeout" in proc.stdout, proc.stdout
    suite = next(iter(JUnitXml.fromfile(str(out / "junit.xml"))))
    props = {p.name: p.value for p in suite.properties()}
    assert props["hil.verdict"] == "INCOMPLETE" and "did not finish" in props["hil.stopped"]
    assert suite.errors == 1 and [c.name for c in suite] == ["run"]
    assert html_badge(out / "report.html") == "INCOMPLETE"


CRASHING_PLUGIN = '''
import pytest

@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    report = yield
    if call.when == "call" and item.name == "test_writes_then_waits":
        raise RuntimeError("a plugin broke")
    return report
'''


def test_an_internal_error_mid_session_says_so_everywhere(tmp_path):
    proc, out = run_tiny(tmp_path, TINY.replace("+ 60", "+ 0"), conftest=CRASHING_PLUGIN)
    assert proc.returncode == 3, proc.stdout
    props = check_stopped(proc, out, "INTERNAL ERROR", "RuntimeError: a plugin broke")
    counts, _, cases = junit_counts(out / "junit.xml")
    assert counts == Counter(passed=1, failed=1)
    assert "a plugin broke" in next(c for c in cases if c.result).result[0].message
    assert props["hil.not_run"] == "1"


def test_a_signal_during_the_sessions_last_restores_still_says_interrupted(tmp_path):
    """hil.core.signals raises a signal that came during a restore once the restore finished: at the session's
    end that is inside pytest_sessionfinish (here a conftest raises it there)."""
    late = "def pytest_sessionfinish(session):\n    raise KeyboardInterrupt('SIGTERM received')\n"
    proc, out = run_tiny(tmp_path, "def test_one(bench):\n    pass\n", conftest=late)
    assert proc.returncode == 2, proc.stdout
    props = junit_counts(out / "junit.xml")[1]
    assert (props["hil.verdict"] == "INTERRUPTED"
            and props["hil.stopped"] == "SIGTERM received at the end of the session")
    assert html_badge(out / "report.html") == "INTERRUPTED"
    assert proc.stdout.splitlines()[-2] == "hil: INTERRUPTED — SIGTERM received at the end of the session"


def test_hil_run_with_two_benches_stopped_by_sigterm_merges_interrupted_reports(tmp_path):
    """The parent passes the signal on, waits for each bench's run to restore and report, then merges."""
    suite = tmp_path / "suite"
    suite.mkdir()
    (suite / "test_tiny.py").write_text(TINY)
    benches = []
    for name in ("bench-a", "bench-b"):
        path = tmp_path / f"{name}.toml"
        path.write_text(re.sub(r'(?m)^name\s*=.*$', f'name = "{name}"', EMULATOR_BENCH.read_text(), count=1))
        benches += ["--bench", str(path)]
    out = tmp_path / "reports"
    (out).mkdir()
    (out / "junit.xml").write_text("<testsuites><testsuite name='earlier' tests='1'/></testsuites>")  # a stale pass
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "PY_COLORS")}
    parent = processes.spawn([sys.executable, "-m", "hil.cli.main", "run", *benches, "--junitxml",
                               str(out / "junit.xml"), "--", str(suite), "-s", "--rootdir", str(suite),
                               "-p", "no:hypothesispytest", "--assert=plain"],
                              cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    logs = [out / "run-bench-a.log", out / "run-bench-b.log"]
    deadline = time.monotonic() + 60
    while not all(log.is_file() and "waiting" in log.read_text() for log in logs):
        assert time.monotonic() < deadline and parent.poll() is None, parent.communicate()[0]
        time.sleep(0.05)
    parent.send_signal(signal.SIGTERM)  # to the parent only, as a CI job's cancel or `timeout` sends it
    stdout, _ = parent.communicate(timeout=60)
    assert parent.returncode == 2, stdout
    merged = JUnitXml.fromfile(str(out / "junit.xml"))
    suites = list(merged)
    assert [s.name for s in suites] == ["bench-a", "bench-b"]
    for suite_ in suites:
        props = {p.name: p.value for p in suite_.properties()}
        assert props["hil.verdict"] == "INTERRUPTED" and "SIGINT received" in props["hil.stopped"], props
        assert suite_.failures == 1
    assert html_badge(out / "report.html") == "INTERRUPTED"
    assert "bench bench-a: INTERRUPTED (exit 2)" in stdout and "tests that did not pass (2):" in stdout, stdout
