"""Helpers of the history tests: a small bench test file, runs of it in their own processes, waiting on the store."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from tests import processes
from tests.conftest import EMULATOR_BENCH, REPO

#: A bench test file: two tests, one that waits for the harness to say go (the harness does something to the run
#: or the store meanwhile), one after it; plus quick ones for runs side by side.
TESTS = '''
import os, time, pathlib
import pytest

def test_first(bench, measure):
    measure("first_value", 1.5, unit="V", low=1, high=2)

def test_second(bench):
    assert bench.plc.io.read("R1000") == 0

def test_waits_for_the_harness(bench):
    go = pathlib.Path(os.environ["HIST_GO"])
    deadline = time.monotonic() + 60
    while not go.exists():
        assert time.monotonic() < deadline, "the harness never said go"
        time.sleep(0.05)

def test_after(bench, measure):
    measure("after_value", 2.5, unit="V", low=2, high=3)

@pytest.mark.parametrize("n", range(12))
def test_quick(bench, measure, n):
    measure("n", n, low=0, high=11)
'''


def write_tests(where: Path) -> Path:
    where.mkdir(parents=True, exist_ok=True)
    path = where / "test_bench_history.py"
    path.write_text(TESTS, encoding="utf-8")
    return path


def bench_profile(where: Path, name: str, source: Path = EMULATOR_BENCH, file: str | None = None,
                  **replace: str) -> Path:
    """A copy of the emulator's profile under another [bench] name (and ``replace``'s texts replaced: old=new)."""
    text = source.read_text(encoding="utf-8").replace('name = "emulator"', f'name = "{name}"', 1)
    for old, new in replace.items():
        assert old in text, old
        text = text.replace(old, new, 1)
    path = where / (file or f"{name}.toml")
    path.write_text(text, encoding="utf-8")
    return path


def env(url: str, **extra: str) -> dict[str, str]:
    out = {**os.environ, "HIL_HISTORY_URL": url, "PYTHONPATH": str(REPO), **extra}
    out.pop("PYTEST_ADDOPTS", None)
    return out


def pytest_run(args: list[str], url: str, cwd: Path, **extra: str) -> subprocess.Popen:
    """One session of the pytest plugin in its own process (its output in ``cwd/out.txt``)."""
    with open(cwd / "out.txt", "wb") as out:  # the child has its own copy of the descriptor once spawned
        return processes.spawn([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", *args], cwd=cwd,
                               env=env(url, **extra), stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)


def wait_for(check, what: str, timeout: float = 60.0):
    """Poll ``check()`` until it returns something true (no timing is asserted: the timeout only ends a hang)."""
    deadline = time.monotonic() + timeout
    while True:
        found = check()
        if found:
            return found
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.1)


def hil(*args: str, url: str, cwd: Path, **extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "hil.cli.main", *args], cwd=cwd, env=env(url, **extra),
                          capture_output=True, text=True, timeout=300)


def history(*args: str, url: str) -> tuple[int, str]:
    """``hil history ARGS --url URL`` in this process (the recording runs are the real processes): exit status and
    what it printed (plain: not a terminal)."""
    import contextlib
    import io

    from hil.cli.main import main
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        code = main(["history", *args, "--url", url])
    return code, out.getvalue()
