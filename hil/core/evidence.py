"""Fresh evidence: a wait that can only be satisfied by what its stimulus produced.

A real PLC answers on its own schedule.  A test that writes a stimulus, then polls for a condition the PLC
*already* showed before the write, passes at once on the previous state — on our emulator (which applies a write
the same scan) by luck, on a bench (a module that measures on its own period) by reading the old answer.  So a
suite looks at its condition before the stimulus, and a condition that already holds then is a defect of the
test, not a verdict on the PLC:

    awaited = bench.expect("TW+3 counts the 9 modules of the new table", lambda: work().module_count == 9)
    temperature.write_table(...)                          # the stimulus
    assert awaited.within(period * 2, every=period / 24), "..."

:func:`expect` evaluates the condition once, at once, and raises :class:`StaleEvidence` (naming the wait) when it
holds; :meth:`Expectation.within` then polls after the stimulus, at ``every``, until the condition holds or the
manual's worst case has passed.  The hil plugin reports a :class:`StaleEvidence` as a test error, not a failure:
it says nothing about the PLC.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from hil.core.errors import HilError
from hil.core.timebase import Timebase

#: looks per limit when a wait gives no cadence of its own
DEFAULT_LOOKS = 24


class StaleEvidence(HilError):
    """A wait's condition held before its stimulus: whatever it sees next cannot prove the stimulus worked."""


def poll_until(clock: Timebase, event: Callable[[], bool], *, every: float, within: float) -> bool:
    """Evaluate ``event`` (a read of the PLC) every ``every`` bench seconds until it holds — True — or ``within``
    bench seconds have passed — False (the caller then asserts what it expects, as after the full wait)."""
    deadline = clock.now() + within
    while True:
        if event():
            return True
        left = deadline - clock.now()
        if left <= 0:
            return False
        clock.wait(min(every, left))


@dataclass(frozen=True)
class Expectation:
    """A condition seen false before its stimulus; :meth:`within` waits for it after the stimulus."""

    what: str
    condition: Callable[[], bool]
    clock: Timebase

    def within(self, seconds: float, *, every: float | None = None) -> bool:
        """Poll the condition every ``every`` bench seconds (default ``seconds`` / 24) for at most ``seconds``;
        True as soon as it holds."""
        if seconds <= 0:
            raise ValueError(f"the wait for {self.what!r} needs a positive limit, not {seconds}")
        return poll_until(self.clock, self.condition, every=every or seconds / DEFAULT_LOOKS, within=seconds)


def expect(clock: Timebase, what: str, condition: Callable[[], bool]) -> Expectation:
    """Look at ``condition`` before the stimulus: :class:`StaleEvidence` naming ``what`` if it already holds."""
    if condition():
        raise StaleEvidence(
            f"the wait for {what!r} was already satisfied before its stimulus, so it cannot show the stimulus "
            f"worked: wait for something the stimulus changes (a value that differs from the one read before it, "
            f"a counter that advances, a measurement cycle that begins after the write)")
    return Expectation(what, condition, clock)


__all__ = ["DEFAULT_LOOKS", "Expectation", "StaleEvidence", "expect", "poll_until"]
