"""A run stopped from the terminal keeps its history (issue 40, item 14): Ctrl-C sends SIGINT to the terminal's
whole foreground group — the run and, before, its history writer, which died first and left the run "NOT FINISHED"
with nothing after the interrupt.  Now the run is recorded as INTERRUPTED with every test it did; a SIGINT as the
run finishes, or a writer gone before the run's end, is no internal error.

Each ``hil run`` is a real process in a group of its own (tests/processes.py), the signal sent to that group as a
terminal sends it; the store is SQLite in the test's directory."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

import hil.history.store  # noqa: F401 - imported once, before anything else in this process could
from tests import processes
from tests.conftest import EMULATOR_BENCH
from tests.history_runs import env, wait_for, write_tests


def _url(tmp: Path) -> str:
    return f"sqlite:///{tmp / 'history.sqlite'}"


def _hil_run(tmp: Path, tests: Path, **extra: str) -> subprocess.Popen:
    """``hil run`` of ``tests`` on the emulator with the history on, its output in ``tmp/out.txt``."""
    with open(tmp / "out.txt", "wb") as out:  # the child has its own copy of the descriptor once spawned
        return processes.spawn([sys.executable, "-m", "hil.cli.main", "run", "--bench", str(EMULATOR_BENCH),
                                "--junitxml", str(tmp / "r" / "junit.xml"), "--html", str(tmp / "r" / "report.html"),
                                "--", str(tests), "-p", "no:cacheprovider"],
                               cwd=tmp, env=env(_url(tmp), **extra), stdout=out, stderr=subprocess.STDOUT,
                               stdin=subprocess.DEVNULL)


def _last_run(tmp: Path) -> tuple[dict, dict[str, str]] | None:
    """The newest run and its tests' outcomes by name (None while there is no store or run yet)."""
    from hil.history.store import Store
    if not (tmp / "history.sqlite").exists():
        return None
    store = Store(_url(tmp))
    try:
        runs = store.runs(limit=1)
        if not runs:
            return None
        return runs[0], {t["nodeid"].split("::")[-1]: t["outcome"] for t in store.tests_of(runs[0]["id"])}
    finally:
        store.close()


def _finished(tmp: Path) -> tuple[dict, dict[str, str]]:
    """The newest run once its end is in the store (the writer, a process of its own, may still be writing it)."""
    return wait_for(lambda: (found := _last_run(tmp)) and found[0]["finished"] and found, "the run's end in the store")


def test_a_run_interrupted_from_the_terminal_is_recorded_as_interrupted_with_its_tests(tmp_path):
    tests = write_tests(tmp_path / "t")
    run = _hil_run(tmp_path, tests, HIST_GO=str(tmp_path / "never"))
    try:
        wait_for(lambda: (found := _last_run(tmp_path)) and {"test_first", "test_second"} <= set(found[1]),
                 "the first two tests in the store")  # the run is now inside test_waits_for_the_harness
    finally:
        code = processes.end(run, signal.SIGINT)  # Ctrl-C: the whole group
    out = (tmp_path / "out.txt").read_text(errors="replace")
    assert code == 2 and "hil: INTERRUPTED" in out, out[-3000:]
    run_row, done = _finished(tmp_path)
    assert run_row["verdict"] == "INTERRUPTED" and "SIGINT received" in run_row["stopped"], run_row
    assert done == {"test_first": "passed", "test_second": "passed", "test_waits_for_the_harness": "aborted"}, done
    assert run_row["not_run"] == 13, run_row  # test_after and the twelve quick ones


FINISHING = '''
import os, signal, time
import pytest


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session):
    """Ctrl-C as the run finishes: the terminal signals the whole group while this process is inside its
    end-of-run restore, which holds the signal back until the PLC is put back (hil.core.signals)."""
    from hil.core import signals
    with signals.shielded():
        os.killpg(0, signal.SIGINT)
        deadline = time.monotonic() + 60  # a hang guard: the signal is this process's own
        while signals._pending is None:
            assert time.monotonic() < deadline, "SIGINT never arrived"
            time.sleep(0.01)
'''

LAST_HOOKS = '''
import os, signal, time
import pytest


@pytest.hookimpl(tryfirst=True)
def pytest_unconfigure(config):
    """Ctrl-C in the run's very last steps (the plugins' ends), once the verdict is out."""
    os.killpg(0, signal.SIGINT)
    deadline = time.monotonic() + 60  # a hang guard: the signal is this process's own, raised here
    while True:
        assert time.monotonic() < deadline, "SIGINT never arrived"
        time.sleep(0.01)
'''

WRITER_GONE = '''
import os, signal, time
import pytest


def _writer() -> int:
    for child in open(f"/proc/{os.getpid()}/task/{os.getpid()}/children").read().split():
        if b"hil.history.writer" in open(f"/proc/{child}/cmdline", "rb").read():
            return int(child)
    raise AssertionError("no history writer among this run's processes")


def _gone(pid: int) -> bool:
    try:
        return open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0] in "ZX"  # exited, not yet reaped
    except FileNotFoundError:
        return True


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session):
    """The history writer gone (killed) before the run's end is sent to it."""
    pid = _writer()
    os.kill(pid, signal.SIGKILL)
    deadline = time.monotonic() + 60  # a hang guard
    while not _gone(pid):
        assert time.monotonic() < deadline, "the writer outlived SIGKILL"
        time.sleep(0.01)
'''


@pytest.mark.parametrize("conftest, code, verdict", [(FINISHING, 2, "INTERRUPTED"), (LAST_HOOKS, 2, "PASSED"),
                                                     (WRITER_GONE, 0, None)],
                         ids=["sigint-as-the-run-finishes", "sigint-in-its-last-steps", "writer-gone-before-the-end"])
def test_the_end_of_a_run_is_no_internal_error(tmp_path, conftest, code, verdict):
    """Both tests passed; at the run's end a SIGINT to the group — during the last restores (recorded: INTERRUPTED,
    both tests) or once the verdict is out (recorded as it was: PASSED) — or the writer killed (one warning; the run
    stays not finished in the store).  Never "internal error", exit 3."""
    tests = tmp_path / "t"
    tests.mkdir()
    (tests / "conftest.py").write_text(conftest)
    (tests / "test_two.py").write_text("def test_one(bench):\n    pass\n\ndef test_two(bench):\n    pass\n")
    run = _hil_run(tmp_path, tests)
    try:
        run.wait(timeout=300)  # a hang guard
    finally:
        returncode = processes.end(run, signal.SIGKILL, grace=0)
    out = (tmp_path / "out.txt").read_text(errors="replace")
    assert returncode == code and "internal error" not in out.lower() and "Traceback" not in out, out[-3000:]
    if verdict is not None:
        run_row, done = _finished(tmp_path)
        assert run_row["verdict"] == verdict and done == {"test_one": "passed", "test_two": "passed"}, (run_row, done)
    else:
        assert "hil: history: its writer stopped" in out and "the rest of this run is not recorded" in out, out[-3000:]
        run_row, done = _last_run(tmp_path)
        assert not run_row["finished"] and done == {"test_one": "passed", "test_two": "passed"}, (run_row, done)
