"""Signals unwind like Ctrl-C, and never abandon a restore.

:func:`install` makes SIGTERM and SIGHUP raise KeyboardInterrupt in the main thread, as SIGINT does, so a run
that is told to stop unwinds through the bench fixture's teardown and restores the PLC.  Inside
:func:`shielded` (the restore) a signal is remembered, not raised: the restore finishes, then the run stops.
A second or third signal while a restore runs changes nothing (the restore still finishes).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator

SIGNALS = tuple(s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None),
                            signal.SIGINT) if s is not None)

_depth = 0  # nesting of shielded() blocks in the main thread
_pending: int | None = None  # a signal that arrived inside a shielded block
_installed: dict[int, object] = {}
_stopping = False  # a signal has already been raised: the run is unwinding; later ones must not abandon that


def _handler(signum: int, frame: object) -> None:
    # pytest's traceback and its "<file>:<line>: KeyboardInterrupt" line skip this frame: they point where the run
    # was when the signal came (the test), not here
    __tracebackhide__ = True
    global _pending, _stopping
    name = signal.Signals(signum).name
    if _depth or _stopping:
        if _pending is None and not _stopping:
            _pending = signum
        with contextlib.suppress(OSError):  # no stderr to say it on: the restore goes on regardless
            os.write(2, f"\nhil: {name} received — restoring the PLC first, then stopping\n".encode())
        return
    _stopping = True
    raise KeyboardInterrupt(f"{name} received")


def install() -> None:
    """SIGTERM, SIGHUP (and SIGINT) → KeyboardInterrupt, deferred while a restore runs.  Main thread only."""
    if threading.current_thread() is not threading.main_thread():
        return
    for signum in SIGNALS:
        if signum in _installed:
            continue
        try:
            previous = signal.signal(signum, _handler)
        except (ValueError, OSError):
            continue
        _installed[signum] = previous


def uninstall() -> None:
    global _stopping
    _stopping = False
    for signum, previous in list(_installed.items()):
        with contextlib.suppress(ValueError, OSError, TypeError):  # not the main thread, or a handler set in C
            signal.signal(signum, previous)  # type: ignore[arg-type]  # None: a handler not set from Python
        del _installed[signum]


@contextlib.contextmanager
def shielded() -> Iterator[None]:
    """Run a restore to its end whatever signals arrive; a signal that came meanwhile is raised afterwards."""
    __tracebackhide__ = True
    global _depth, _pending, _stopping
    main = threading.current_thread() is threading.main_thread()
    if main:
        _depth += 1
    try:
        yield
    finally:
        if main:
            _depth -= 1
            if _depth == 0 and _pending is not None:
                signum, _pending = _pending, None
                _stopping = True
                if sys.exc_info()[0] is None:
                    raise KeyboardInterrupt(f"{signal.Signals(signum).name} received")


__all__ = ["install", "uninstall", "shielded"]
