"""A PLC's clock as the guard keeps it: what a family declares (:class:`Clock`), the clock's origin
(:class:`ClockOrigin`: its time at a moment of the bench's monotonic reference), and whether a dead run's
journaled origin may still be carried to now (:func:`origin_from_journal`).

Pure: nothing here reads or writes a PLC; :mod:`hil.bench.clock_keeper` does, with these.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from hil.core.errors import HilError
from hil.core.timebase import HostClocks, Timebase


@dataclass(frozen=True)
class Clock:
    """A clock the PLC keeps that a test may set, as the family declares it to the guard."""

    touches: frozenset[Any]  # elements a write to which may set the clock (empty: only a clock function sets it)
    read: Callable[[], dt.datetime | None]  # the PLC's time now; None when it holds no valid time
    #: set it to ``when()`` — ``exact``: at ``when``'s next whole second (a clock restarts its second when set),
    #: else at once, to the nearest second; HilError when the PLC refuses
    put: Callable[[Callable[[], dt.datetime], bool], None]
    timebase: Timebase  # the bench's time: virtual on an in-process emulator, else the host's × its time scale
    #: the clock's next second transition: (its time then, the timebase's time of it, ± twice how well that is
    #: known); HilError when it does not tick.  None: the origin is a plain read, and an exact put is not read back
    transition: Callable[[], tuple[dt.datetime, float, float]] | None = None


#: recovery refuses a journaled clock origin older than this (host seconds): carried further, the host clock's
#: steps across reboots (which nothing can detect) and the PLC crystal's own drift make its offset a guess
ORIGIN_MAX_AGE = 24 * 3600.0
#: what a float's reading of the host clocks can tell apart (s): below the spread of any two reads
CLOCK_RESOLUTION = 1e-6


@dataclass(frozen=True)
class ClockOrigin:
    """The PLC's time ``plc`` when the bench's timebase said ``at`` (:meth:`Timebase.now`: monotonic, so a step of
    the host's wall clock moves nothing); a PLC second is one bench second (``scale`` host seconds⁻¹)."""

    plc: dt.datetime
    at: float
    scale: float
    width: float = 0.0  # ``at`` is known to ± half this (the bracket of the transition it was timed at)
    #: a dead run's origin carried by the host's boot clock across a step of its wall clock: the step (s), else 0
    host_step: float = 0.0

    def original(self, timebase: Timebase) -> dt.datetime:
        """The PLC's original time carried forward to now: its offset from the reference kept."""
        return self.plc + dt.timedelta(seconds=timebase.now() - self.at)


class OriginRefused(HilError):
    """A dead run's clock origin that cannot be carried to now (too old, or the host clock stepped since)."""


class HostClockUnproven(OriginRefused):
    """A dead run's clock origin from another boot of the host (or a host whose boot clock cannot be read): nothing
    can tell whether its wall clock was stepped since — only a person can accept it (``--accept-host-clock``)."""


def origin_from_journal(entry: dict[str, Any], timebase: Timebase, host: HostClocks, *,
                        accept_host_clock: bool = False) -> ClockOrigin:
    """A journaled clock origin (PLC time at host wall time ``host``, ×``scale``) on this session's ``timebase``.

    From this boot of the host it is carried by the boot clock — the reference a live session keeps the origin on
    (monotonic, suspend included), which no step of the wall clock moves; a step is measured (the wall clock and
    the boot clock disagreeing about the time since by more than the journal's own measurement allows,
    :func:`step_bound`) and reported on the origin, not carried.  From another boot — or where the boot clock cannot
    be compared — only the wall clock spans the time since, and nothing can tell whether it was stepped: refused
    (:class:`HostClockUnproven`) unless ``accept_host_clock``.  Refused too when older than :data:`ORIGIN_MAX_AGE`
    or in the future.  Raises :class:`OriginRefused` saying which, with the figures."""
    plc, wall, scale = dt.datetime.fromisoformat(entry["plc"]), float(entry["host"]), float(entry["scale"])
    elapsed = host.wall - wall
    bound = step_bound(entry, host)
    booted = entry.get("since_boot")
    same_boot, passed = False, elapsed  # (the time since, on the clock that spans it)
    if host.boot is not None and entry.get("boot") == host.boot and booted is not None and host.since_boot is not None:
        same_boot, passed = True, host.since_boot - float(booted)
    if passed < -bound:
        raise OriginRefused(f"its host time is {-passed:.6f} s in the future: the host clock was set back since")
    if passed > ORIGIN_MAX_AGE:
        raise OriginRefused(f"it is {passed / 3600:.1f} h old (limit {ORIGIN_MAX_AGE / 3600:.0f} h): too long to "
                            f"carry its offset from host time")
    if not same_boot and not accept_host_clock:
        raise HostClockUnproven(_unproven(entry, host, elapsed))
    step = elapsed - passed
    return ClockOrigin(plc, timebase.now() - passed * scale, scale, host_step=step if abs(step) > bound else 0.0)


def step_bound(entry: dict[str, Any], host: HostClocks) -> float:
    """How far the host's wall clock and boot clock may disagree about the time since a journaled origin without
    a step (s): half the origin's own bracket (``width``, host seconds) and half of each reading's spread of the
    two host clocks (then and now) — what the journal measured, nothing assumed."""
    width, spread = entry.get("width", 0.0), entry.get("spread", 0.0)
    measured = sum(float(v) for v in (width, spread) if isinstance(v, (int, float)) and v >= 0)
    return (measured + host.spread) / 2 + CLOCK_RESOLUTION


def _unproven(entry: dict[str, Any], host: HostClocks, elapsed: float) -> str:
    if host.boot is None or host.since_boot is None:
        why = "this host's boot clock cannot be read"
    elif entry.get("boot") is None or entry.get("since_boot") is None:
        why = "the journal has no boot clock reading"
    else:
        why = f"it was journaled during another boot of this host (boot {entry['boot']}, now {host.boot})"
    return (f"{why}, so nothing can tell whether the host's wall clock was stepped in the {elapsed:.0f} s since — "
            f"not set from it; `hil restore --bench FILE --accept-host-clock` sets the PLC's clock from the host "
            f"clock as it is now, if you know it is right")


__all__ = ["CLOCK_RESOLUTION", "ORIGIN_MAX_AGE", "Clock", "ClockOrigin", "HostClockUnproven", "OriginRefused",
           "origin_from_journal", "step_bound"]
