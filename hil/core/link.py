"""The lifecycle every link to a PLC shares, whatever it speaks: one request at a time, closers, context manager."""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator

from hil.core.errors import TransportError


class Link:
    """Base of :class:`hil.families.fbs.transport.base.Transport` and the S7-200 SMART link."""

    def __init__(self, description: str) -> None:
        self.description = description
        # one request on the wire at a time, as a serial line demands; a subclass may hold a line shared with other
        # processes instead (hil.io.shared_line.SharedLine): any re-entrant context manager does
        self._lock: contextlib.AbstractContextManager[object] = threading.RLock()
        self._closers: list[Callable[[], None]] = []
        self.requests = 0  # protocol requests sent (round trips)
        self.closed = False

    @contextlib.contextmanager
    def exclusive(self) -> Iterator[None]:
        """Hold the wire across several requests: where other processes take turns on it (a run's lanes on one
        serial line, :mod:`hil.io.shared_line`), none of theirs comes between — for a step whose timing matters
        (a set and an edge that must land within one second of the PLC's clock)."""
        with self._lock:
            yield

    def on_close(self, closer: Callable[[], None]) -> None:
        """Run ``closer`` after this link closes (e.g. stop the server of an ``emulator+…`` target)."""
        self._closers.append(closer)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        with self._lock:
            try:
                self._close()
            finally:
                for closer in reversed(self._closers):
                    closer()

    def reopen(self) -> None:
        """Reconnect the wire after a failure (same target; an emulator's server keeps running)."""
        raise TransportError(f"{self.description} cannot be reopened")

    def _close(self) -> None:
        pass

    def __enter__(self):  # noqa: ANN204 - returns the subclass
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.description}>"
