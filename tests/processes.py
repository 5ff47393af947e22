"""The tests' child processes (``hil emulate``, a ``hil run`` or pytest run to kill): each in a process group of its
own, so that what it starts in turn (pytest-xdist workers, a lane) goes with it, and each ended by the test that
started it or, failing that, by the test's teardown (tests/conftest.py) — an interrupted run (Ctrl-C, SIGINT to
the controller, pytest-xdist stopping a worker) leaves no process behind.

A group of its own also keeps a terminal's Ctrl-C from reaching the child before the test has decided how to stop
it: ``end`` sends the signal the test asked for, then SIGKILL to the group once the grace period has run out.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
from typing import Any

#: the process groups started by this process and not yet ended (their leaders' pids)
_LIVE: dict[int, subprocess.Popen] = {}


def spawn(args: list[str], **kwargs: Any) -> subprocess.Popen:
    """``subprocess.Popen(args, **kwargs)`` in a new process group, remembered until :func:`end`."""
    if not kwargs.get("start_new_session"):  # a session of its own is a group of its own already (setsid)
        kwargs["process_group"] = 0
    proc = subprocess.Popen(args, **kwargs)
    _LIVE[proc.pid] = proc
    return proc


def run(args: list[str], *, timeout: float, **kwargs: Any) -> subprocess.CompletedProcess:
    """``subprocess.run(args, capture_output=True, text=True, ...)`` in a new process group: on a timeout or an
    interrupt the whole group is killed, not just its leader."""
    kwargs.setdefault("stdout", subprocess.PIPE)
    kwargs.setdefault("stderr", subprocess.PIPE)
    kwargs.setdefault("text", True)
    proc = spawn(args, **kwargs)
    try:
        out, err = proc.communicate(timeout=timeout)
    except BaseException:
        end(proc, signal.SIGKILL, grace=0)
        raise
    signal_group(proc, signal.SIGKILL)  # anything it left running in its group
    _LIVE.pop(proc.pid, None)
    return subprocess.CompletedProcess(args, proc.returncode, out, err)


def signal_group(proc: subprocess.Popen, sig: int) -> None:
    """Send ``sig`` to ``proc``'s whole group (nothing when it is gone already)."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, sig)


def end(proc: subprocess.Popen, sig: int = signal.SIGINT, grace: float = 30.0) -> int:
    """Stop ``proc``'s group: ``sig``, then SIGKILL to the group if its leader has not exited within ``grace``
    seconds (a hang guard: a healthy child exits at once).  Returns the leader's exit code."""
    try:
        if proc.poll() is None:
            signal_group(proc, sig)
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=grace)
        signal_group(proc, signal.SIGKILL)  # the leader's own children, whether or not it has gone
        proc.wait()
    finally:
        _LIVE.pop(proc.pid, None)
    return proc.returncode


def running() -> set[int]:
    """The groups started and not yet ended (their leaders' pids)."""
    return set(_LIVE)


def end_all(grace: float = 3.0, *, but: set[int] = frozenset()) -> None:
    """End every group still running but those of ``but`` (a wider fixture's): a test that was interrupted or
    failed before its own ``end``."""
    for pid, proc in list(_LIVE.items()):
        if pid not in but:
            end(proc, signal.SIGINT, grace)
