"""An S7-200 SMART run that dies leaves the CPU as it found it, like an FBs run (issue 15 through the one guard).

``hil emulate --s7-tcp`` runs as a separate process at time scale 20; the S7 suites run in a child process over
s7+tcp:// and are SIGKILLed while a test has the CPU changed (its journal pending), at moments spread over the
suites; then the next session runs (a fresh process: the bench lock, recovery first).  Before the first run and
after every next session, V memory, the Q bits and the CPU clock (as its offset from host time) are read over the
S7 wire with python-snap7's own client, and must be what they were.
"""

from __future__ import annotations

import datetime as dt
import os
import re
import signal
import subprocess
import sys
import time

import pytest

from hil.core.journal import Journal
from hil.core.lock import lock_key
from tests import processes
from tests.conftest import REPO
from tests.external import emulate_process

snap7 = pytest.importorskip("snap7", reason="python-snap7 (pip install 'hil[s7]') is not installed")
S7_BENCH = REPO / "fixtures" / "benches" / "s7-200smart.toml"
TIME_SCALE = 20
V_BYTES = 2048  # every V byte the bench's layouts and allow-list name lies below this
DELAYS = (0.0, 0.6, 1.2, 1.8)  # bench-host seconds after the first pending journal: spread over the suites
NEXT_SESSION = ('import pytest\n\npytestmark = pytest.mark.family("s7-200smart")\n\n\n'
                'def test_next_session(bench):\n    pass\n')


def snapshot(address: str) -> dict[str, object]:
    """V memory, Q and the clock's offset from host time (PLC seconds), with python-snap7's own client."""
    host, port = address.rsplit(":", 1)
    client = snap7.client.Client()
    client.connect(host, 0, 1, int(port))
    try:
        v = b"".join(bytes(client.db_read(1, first, 200)) for first in range(0, V_BYTES, 200))[:V_BYTES]
        q = bytes(client.read_area(snap7.type.Area.PA, 0, 0, 32))
        clock = client.get_plc_datetime()
        host_now = time.time()
    finally:
        client.disconnect()
    out: dict[str, object] = {f"VB{i}": b for i, b in enumerate(v)}
    out.update({f"QB{i}": b for i, b in enumerate(q)})
    out["clock offset"] = (clock - dt.datetime(1970, 1, 1)).total_seconds() - host_now * TIME_SCALE
    return out


def differences(before: dict, after: dict) -> list[str]:
    diff = [f"{k}: {before[k]:02X} → {after[k]:02X}" for k in before if k != "clock offset" and before[k] != after[k]]
    # whole seconds and a request's latency on either side: 2 host seconds of slack
    moved = after["clock offset"] - before["clock offset"]
    if abs(moved) > 2 * TIME_SCALE:
        diff.append(f"clock offset from host time moved by {moved:.0f} s")
    return diff


def _until_pending(key: str, child: subprocess.Popen, limit: float = 30.0) -> bool:
    """Wait until a test of the running suites has the CPU changed (its journal pending)."""
    deadline = time.monotonic() + limit
    while not Journal(key).pending and child.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    return Journal(key).pending


@pytest.mark.matrix  # the gate kills FBs runs (tests/test_kill_recovery.py); the S7 recovery is in-process too
@pytest.mark.timeout(180)  # 10–20 s; child processes start slowly on a loaded host
def test_killed_s7_runs_leave_the_cpu_as_they_found_it(tmp_path):
    with emulate_process(S7_BENCH, TIME_SCALE, {"s7-tcp": "--s7-tcp"}) as where:
        target = f"s7+tcp://{where['s7-tcp']}"
        profile = tmp_path / "s7-bench.toml"
        text = re.sub(r"(?m)^target = .*$", f'target = "{target}"', S7_BENCH.read_text())
        profile.write_text(text.replace("[bench]", f"[bench]\ntime_scale = {TIME_SCALE}", 1))
        (tmp_path / "next").mkdir()
        (tmp_path / "next" / "test_next.py").write_text(NEXT_SESSION)
        key = lock_key(target)
        inner = ["-p", "no:cacheprovider", "-p", "no:hypothesispytest", "--bench", str(profile), "-q"]
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        first = snapshot(where["s7-tcp"])
        problems, clock_left, changed_left = [], 0, 0
        for delay in DELAYS:
            label = f"SIGKILL {delay} s into the suites"
            child = processes.spawn([sys.executable, "-m", "pytest", str(REPO / "suites" / "s7smart"), *inner],
                                     cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True)
            pending = _until_pending(key, child)
            time.sleep(delay)
            pending = pending and _until_pending(key, child)
            child.send_signal(signal.SIGKILL)
            out, _ = child.communicate(timeout=30)
            if not pending:
                problems.append(f"{label}: the run never had a journal pending on disk: {out[-800:]}")
                break
            journal = Journal(key)
            clock_left += journal.clock() is not None
            left = differences(first, snapshot(where["s7-tcp"]))
            changed_left += bool(left)
            if left and not journal.pending:
                problems.append(f"{label}: the CPU was left changed ({'; '.join(left[:6])}) with nothing journaled")
            nxt = subprocess.run([sys.executable, "-m", "pytest", str(tmp_path / "next"), *inner], cwd=tmp_path,
                                 env=env, capture_output=True, text=True, timeout=60)
            if nxt.returncode != 0:
                problems.append(f"{label}: the next session failed: {nxt.stdout[-2000:]}")
            if left and "hil bench recovery: a previous run" not in nxt.stdout:
                problems.append(f"{label}: the next session did not say it recovered: {nxt.stdout[-1000:]}")
            diff = differences(first, snapshot(where["s7-tcp"]))
            if diff:
                problems.append(f"{label}: after the next session: {'; '.join(diff[:12])} — {out[-800:]}")
            if Journal(key).pending:
                problems.append(f"{label}: a journal is still pending: {Journal(key).describe()}")
    print(f"{changed_left} of {len(DELAYS)} kills left the CPU changed, {clock_left} with its clock journaled")
    assert not problems, "\n".join(problems)
    # the kills must land while the suites have the CPU changed, its clock among it, or this proves nothing
    assert changed_left >= 1, f"none of {len(DELAYS)} kills left the CPU changed"
    assert clock_left >= 1, "no kill landed while a test had the CPU clock set"
