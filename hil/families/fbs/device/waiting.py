"""Waiting for an event on the PLC: look at the cadence of what is awaited, give up at the manual's worst case.

A poll is a request on the wire; on port 0 at 9600 bit/s a read of a few words takes 30–60 ms of the line, so
reading back to back while nothing can change only fills the line.  What is awaited has its own clock — a
temperature module measures each point once per update period, FUN86 steps once per PID interval (R4005), the
RTC's second once a second — and the procedures poll at a fraction of it (:func:`poll_until`), so an event is
seen within that fraction of its own period, and the limit is the worst case the manual allows, never a wait for
the limit itself.
"""

from __future__ import annotations

from collections.abc import Callable

from hil.core import evidence
from hil.core.timebase import Timebase

#: looks per period of what is awaited: an event is seen within 1/POLLS_PER_PERIOD of its period (4 %)
POLLS_PER_PERIOD = 24


def poll_until(clock: Timebase, event: Callable[[], bool], *, period: float, within: float) -> bool:
    """Evaluate ``event`` (a read of the PLC) every ``period`` / :data:`POLLS_PER_PERIOD` bench seconds until it
    holds — True — or ``within`` bench seconds have passed — False (a test then asserts what it expects, as it
    would after the full wait)."""
    return evidence.poll_until(clock, event, every=period / POLLS_PER_PERIOD, within=within)


__all__ = ["poll_until", "POLLS_PER_PERIOD"]
