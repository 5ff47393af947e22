"""One request policy for every wire: how often a request is tried, the pause between tries, what a failed write
means, how the line is brought back in step after a fault, and the time one request may take (issue 28;
pymodbus's transaction manager keeps the same rules for its own client).

The rules, the same on FATEK, Modbus and S7:

* a **read** is tried ``1 + retries`` times; between tries the wire recovers (``recover``: a reconnect) and pauses
  :meth:`RequestPolicy.pause` — doubling from ``backoff``, at most 8× it;
* a **write** is sent once: when its reply never came the write may or may not have landed, and it is reported as
  :class:`~hil.core.errors.OutcomeUnknown`, never silently repeated;
* a reply that refuses the request (the PLC answered with an error) is final: it is not a lost request;
* after a fault a late reply may still be on the way, and a wire without transaction ids would take it for the
  next request's answer: while the wire says so (:attr:`Resync.needed`), the next request is preceded by a
  resynchronising probe (a loop-back, a probe read, a new connection) — one per try of a read (its tries are the
  retries), up to ``1 + retries`` before a write (it has no tries of its own to spare, and it must not go out on
  a line that is out of step).  When every probe failed nothing was sent: a ReplyTimeout, never OutcomeUnknown.

A wire supplies only its own parts — one try (send and receive), what counts as a lost request, the probe — and
:meth:`RequestPolicy.run` applies the rules.  :meth:`RequestPolicy.budget` is the longest a request may take
under them (the soak checks no call runs past it).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

from hil.core.errors import InvalidValue, OutcomeUnknown, ReplyTimeout, TransportError

T = TypeVar("T")
Lost = tuple[type[BaseException], ...]


@dataclass(frozen=True)
class Resync:
    """How a wire gets back in step before its next request, after a fault."""

    needed: Callable[[], bool]  # True: a late reply may be on the line, or the connection is gone
    #: one probe (``probe(n, tries)``); raises one of the request's ``lost`` kinds when the line is not in step yet
    probe: Callable[[int, int], None]
    failed: Callable[[str], str]  # the error when every probe failed, given the last probe's failure


@dataclass(frozen=True)
class RequestPolicy:
    retries: int = 2
    backoff: float = 0.05

    def __post_init__(self) -> None:
        if self.retries < 0:
            raise InvalidValue(f"retries must be 0 or more, not {self.retries}")
        if self.backoff < 0:
            raise InvalidValue(f"backoff must be 0 s or more, not {self.backoff}")

    def tries(self, write: bool = False) -> int:
        return 1 if write else 1 + self.retries

    def pause(self, attempt: int) -> float:
        """Seconds before try ``attempt + 1``: doubling from ``backoff``, at most 8× it."""
        return self.backoff * min(2 ** (attempt - 1), 8)

    def pauses(self, tries: int) -> float:
        """The pauses between ``tries`` tries, in all."""
        return sum(self.pause(a) for a in range(1, tries))

    def budget(self, one_try: float, write: bool = False, probe: float = 0.0) -> float:
        """The longest one request takes when each try takes at most ``one_try`` seconds and each resynchronising
        probe at most ``probe`` (0: the wire has none)."""
        if write:
            probes = self.tries() if probe else 0
            return probes * probe + self.pauses(probes) + one_try
        tries = self.tries()
        return tries * (probe + one_try) + self.pauses(tries)

    def run(self, what: str, attempt: Callable[[int, int], T], *, write: bool, lost: Lost,
            recover: Callable[[], None] = lambda: None, resync: Resync | None = None,
            timeouts: Lost | None = None, one_try: float | None = None) -> T:
        """``attempt(n, tries)`` under the rules: an exception in ``lost`` is a request whose reply never came (a
        write's: OutcomeUnknown; a read's: ``recover()``, pause, try again; after the last try a ReplyTimeout — a
        TransportError when the last failure is not one of ``timeouts`` (default: every lost kind) — naming it,
        and how many tries of ``one_try`` seconds took how long); anything else (a refusal) goes to the caller as
        it is.  ``resync``: the wire's probe, run before a try while it is needed.  ``what`` (when not empty)
        heads every message."""
        head = f"{what}: " if what else ""
        tries = self.tries(write)
        failures: list[tuple[str, bool, bool]] = []  # (what went wrong, a timeout, before anything was sent)
        started = time.monotonic()
        for n in range(1, tries + 1):
            if n > 1:
                time.sleep(self.pause(n - 1))
            if resync is not None and resync.needed():
                why = self._resync(resync, 1 + self.retries if write else 1, lost)
                if why is not None:
                    if write:  # nothing was sent: the PLC is as it was
                        raise ReplyTimeout(head + why)
                    failures.append((why, True, True))
                    continue
            try:
                return attempt(n, tries)
            except lost as exc:
                if write:
                    raise OutcomeUnknown(f"{head}{exc} — the write may or may not have been applied: outcome "
                                         f"unknown (writes are not retried)") from None
                failures.append((str(exc), timeouts is None or isinstance(exc, timeouts), False))
            recover()
        text, timeout, unsent = failures[-1]
        sent = [f for f, _, before in failures if not before]
        if unsent and sent:  # the probe failed last: what went wrong with the request itself first
            text = f"{sent[0]}; then {text}"
        if tries > 1:
            of = f" of {one_try:g} s ({tries * one_try:g} s)" if one_try else ""
            text += f"; {tries} tries{of}, {time.monotonic() - started:.2f} s in all"
        raise (ReplyTimeout if timeout else TransportError)(head + text)

    def _resync(self, resync: Resync, probes: int, lost: Lost) -> str | None:
        """Up to ``probes`` probes, paused as tries are; None once one answered, else why the request is not sent."""
        last = ""
        for n in range(1, probes + 1):
            if n > 1:
                time.sleep(self.pause(n - 1))
            try:
                resync.probe(n, probes)
                return None
            except lost as exc:
                last = str(exc)
        return resync.failed(last)


__all__ = ["RequestPolicy", "Resync"]
