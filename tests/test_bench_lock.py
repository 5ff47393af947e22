"""Two harness runs against one bench do not interleave: the second waits or refuses, naming the holder."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from hil.core.lock import BenchBusy, BenchLock

TARGET = "fatek+tcp://127.0.0.1:1"


def _holder(tmp_path, seconds: float) -> subprocess.Popen:
    """Another process that takes the bench lock and keeps it for ``seconds``."""
    code = textwrap.dedent(f"""
        import sys, time
        from hil.core.lock import BenchLock
        lock = BenchLock({TARGET!r}).acquire()
        print("locked", flush=True)
        time.sleep({seconds})
        lock.release()
    """)
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "HIL_LOCK_DIR": str(tmp_path)})
    assert proc.stdout.readline().strip() == "locked"
    return proc


@pytest.fixture(autouse=True)
def lock_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("HIL_LOCK_DIR", str(tmp_path))


def test_second_run_refuses_naming_the_holder(tmp_path):
    proc = _holder(tmp_path, 30)
    try:
        with pytest.raises(BenchBusy) as info:
            BenchLock(TARGET).acquire()
        holder = info.value.holder
        assert holder["pid"] == proc.pid and holder["host"] and holder["user"] and holder["started"]
        assert "hil.core.lock" in holder["command"] or "-c" in holder["command"]
        assert f"pid {proc.pid}" in str(info.value) and "--hil-lock-wait" in str(info.value)
    finally:
        proc.kill()
        proc.wait()


def test_second_run_waits_for_the_first(tmp_path):
    proc = _holder(tmp_path, 0.8)
    try:
        started = time.monotonic()
        with BenchLock(TARGET).acquire(wait=10) as lock:
            assert time.monotonic() - started > 0.3  # it waited for the holder (who holds 0.8 s) to let go
            assert lock.stale is None  # released cleanly
            assert lock.holder()["pid"] == os.getpid()
    finally:
        proc.wait()


def test_wait_gives_up_after_its_timeout(tmp_path):
    proc = _holder(tmp_path, 30)
    try:
        started = time.monotonic()
        with pytest.raises(BenchBusy, match="waited"):
            BenchLock(TARGET).acquire(wait=0.5)
        assert time.monotonic() - started > 0.4  # it waited (about) its 0.5 s before giving up
    finally:
        proc.kill()
        proc.wait()


def test_a_dead_holders_lock_is_recovered_and_reported(tmp_path):
    proc = _holder(tmp_path, 30)
    os.kill(proc.pid, signal.SIGKILL)  # dies holding it: the kernel drops the flock, the record stays
    proc.wait()
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
    proc = _holder(tmp_path, 30)
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
        result.stderr.fnmatch_lines([f"ERROR: hil: cannot open bench *bench {TARGET}*is in use by pid {proc.pid} on "
                                     f"*waited*"])
    finally:
        proc.kill()
        proc.wait()
