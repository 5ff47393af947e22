"""Two harness runs against one bench do not interleave: the second waits or refuses, naming the holder."""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from types import SimpleNamespace

import pytest

import hil.core.lock as lock_module
from hil.core.lock import BenchBusy, BenchLock

TARGET = "fatek+tcp://127.0.0.1:1"


def _holder(tmp_path) -> subprocess.Popen:
    """Another process that takes the bench lock and keeps it until told to let go (a line on its stdin, or its
    stdin closed); it says "releasing" just before it does.  No host time decides anything: the test says when."""
    code = textwrap.dedent(f"""
        import sys
        from hil.core.lock import BenchLock
        lock = BenchLock({TARGET!r}).acquire()
        print("locked", flush=True)
        sys.stdin.readline()
        print("releasing", flush=True)
        lock.release()
    """)
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "HIL_LOCK_DIR": str(tmp_path)})
    assert proc.stdout.readline().strip() == "locked"
    return proc


def _end(proc: subprocess.Popen) -> None:
    proc.kill()
    proc.wait(60)  # hang guard: a killed process is reaped at once
    proc.stdin.close()
    proc.stdout.close()


@pytest.fixture(autouse=True)
def lock_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("HIL_LOCK_DIR", str(tmp_path))


def test_second_run_refuses_naming_the_holder(tmp_path):
    proc = _holder(tmp_path)
    try:
        with pytest.raises(BenchBusy) as info:
            BenchLock(TARGET).acquire()
        holder = info.value.holder
        assert holder["pid"] == proc.pid and holder["host"] and holder["user"] and holder["started"]
        assert "hil.core.lock" in holder["command"] or "-c" in holder["command"]
        assert f"pid {proc.pid}" in str(info.value) and "--hil-lock-wait" in str(info.value)
    finally:
        _end(proc)


def test_second_run_waits_for_the_first(tmp_path, monkeypatch):
    """The waiter is refused while the holder holds the lock and gets it once the holder lets go: the order of those
    events is the claim, so the holder lets go only after the waiter has been refused at least once."""
    refused = threading.Event()  # the waiter found the lock held (at least once)
    decided = threading.Event()  # … or acquire() came back
    flock = fcntl.flock

    def counting_flock(fd, operation):
        try:
            return flock(fd, operation)
        except BlockingIOError:
            refused.set()
            decided.set()
            raise

    monkeypatch.setattr(lock_module, "fcntl", SimpleNamespace(flock=counting_flock, LOCK_EX=fcntl.LOCK_EX,
                                                              LOCK_NB=fcntl.LOCK_NB, LOCK_UN=fcntl.LOCK_UN))
    proc = _holder(tmp_path)
    got: list[BenchLock] = []
    failed: list[BaseException] = []

    def waiter() -> None:
        try:
            got.append(BenchLock(TARGET).acquire(wait=600))  # the wait a hang guard: the holder is told below
        except BaseException as exc:  # noqa: BLE001 - reported from the test's thread
            failed.append(exc)
        finally:
            decided.set()

    thread = threading.Thread(target=waiter, daemon=True)
    try:
        thread.start()
        assert decided.wait(60), "hang guard: the waiter neither found the lock held nor got it within 60 s"
        assert refused.is_set() and not got and not failed, (f"the waiter did not wait for the holder "
                                                              f"({got or failed})")
        proc.stdin.write("let go\n")
        proc.stdin.flush()
        assert proc.stdout.readline().strip() == "releasing"
        thread.join(60)
        assert not thread.is_alive(), "hang guard: the waiter did not get the released lock within 60 s"
        assert not failed, failed
        with got[0] as lock:
            assert lock.stale is None  # released cleanly
            assert lock.holder()["pid"] == os.getpid()
    finally:
        _end(proc)


def test_wait_gives_up_after_its_timeout(tmp_path):
    proc = _holder(tmp_path)
    try:
        started = time.monotonic()
        with pytest.raises(BenchBusy, match="waited") as info:
            BenchLock(TARGET).acquire(wait=0.5)
        # a guaranteed lower bound: acquire() gives up only once its own monotonic clock says 0.5 s have passed
        # (a busy host can only make it later; how much later is not this test's business)
        assert info.value.waited >= 0.5
        assert time.monotonic() - started >= 0.5
    finally:
        _end(proc)


def test_a_dead_holders_lock_is_recovered_and_reported(tmp_path):
    proc = _holder(tmp_path)
    os.kill(proc.pid, signal.SIGKILL)  # dies holding it: the kernel drops the flock, the record stays
    _end(proc)
    with BenchLock(TARGET).acquire() as lock:
        assert lock.stale is not None and lock.stale["pid"] == proc.pid


def test_in_process_emulator_targets_take_no_lock(tmp_path):
    from tests.conftest import EMULATOR_BENCH
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--bench",
                           str(EMULATOR_BENCH), "--target", "emulator+fatek-tcp",
                           str(EMULATOR_BENCH.parent.parent.parent / "suites" / "test_smoke.py")],
                          capture_output=True, text=True, env={**os.environ, "HIL_LOCK_DIR": str(tmp_path)},
                          cwd=EMULATOR_BENCH.parent.parent.parent, timeout=120)
    assert proc.returncode == 0, proc.stdout[-2000:]
    assert not list(tmp_path.glob("bench-*.lock"))


def test_plugin_refuses_a_bench_another_run_holds(tmp_path, pytester):
    proc = _holder(tmp_path)
    try:
        bench = pytester.makefile(".toml", bench=f"""
            [bench]
            name = "real"
            target = "{TARGET}"
        """)
        pytester.makepyfile(test_one="def test_one(bench):\n    pass\n")
        result = pytester.runpytest_inprocess("--bench", str(bench), "--hil-lock-wait", "0.2", "-p",
                                              "no:cacheprovider")
        # before anything is collected: one line naming the holder, exit 4 (hil.plugin.preflight)
        assert result.ret == 4
        result.stderr.fnmatch_lines([f"hil: error: cannot open bench *bench {TARGET}*is in use by pid {proc.pid} on "
                                     f"*waited*"])
    finally:
        _end(proc)
