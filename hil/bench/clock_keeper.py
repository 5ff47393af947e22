"""The guard's keeping of the PLC's clock: its origin taken (and journaled, on disk first) before the first write
that may set it, and the clock put back at that origin's *offset* from the bench's time — to within half a second
after a test, exactly when the session ends — and, for a dead run, from the journaled origin.

:class:`ClockKeeper` holds the clock's state in a session; the guard (:mod:`hil.bench.guard`) calls it around its
writes and restores.  What may be carried from a journal is decided in :mod:`hil.bench.clock`.
"""

from __future__ import annotations

import contextlib
import datetime as dt
from collections.abc import Callable

from hil.bench.clock import Clock, ClockOrigin, OriginRefused, origin_from_journal
from hil.bench.putback import Failure
from hil.bench.replay import Recovery, age_problem
from hil.core.errors import HilError
from hil.core.journal import CLOCK, Journal
from hil.core.timebase import HostClocks, Timebase

NO_CLOCK = "this bench has no way to set the clock"


class ClockKeeper:
    """The clock of one guarded link, as the family declares it (:attr:`clock`, None: it keeps none the tests set)."""

    TRIES = 3  # exact sets tried before settling for ROUGH
    ROUGH = 0.5  # bench seconds: what the per-test restore promises, and all an exact one falls back to

    def __init__(self) -> None:
        self.clock: Clock | None = None
        # the clock before the session's (or a dead run's) first write that may set it; kept, and journaled,
        # until the session's end puts it back exactly
        self.origin: ClockOrigin | None = None
        self.due = False  # a test may have set the clock and it is not put back yet
        self.held = False  # a suite holds it (hil.bench.guard.Guard.hold): put back when the hold ends
        self.busy = False  # the guard is reading or putting back the clock itself
        self.error: float | None = None  # seconds the last exact put left it off, read back (None: not read)

    def touched_by(self, elements: list[object]) -> bool:
        """Whether a write to ``elements`` may set the clock."""
        return self.clock is not None and bool(self.clock.touches.intersection(elements))

    def due_now(self, exact: bool) -> bool:
        """Whether a restore puts the clock back now: a test may have set it and no hold keeps it — or, ``exact``,
        it still has an origin to end."""
        return (self.due and not self.held) or (exact and self.origin is not None)

    def pending(self) -> tuple[str, str] | None:
        """("clock", how it goes back) while it is due, for the list of what is still to be put back."""
        if not self.due:
            return None
        origin = self.origin
        return ("clock", f"{origin.plc:%Y-%m-%d %H:%M:%S}, kept at its offset from the bench's time"
                if origin is not None else "on the bench's time")

    # -- before a write that may set it ---------------------------------------------------------------------------
    def note(self, durable: Journal | None) -> None:
        """Before the first write that may set the clock: its origin, on disk first (in ``durable``)."""
        if self.busy:
            return
        if self.origin is None and self.clock is not None:
            self.busy = True
            try:
                origin = self.take_origin(self.clock)
            finally:
                self.busy = False
            # None (no valid time): there is no offset to keep; the restore puts it on the bench's time
            if origin is not None:
                if durable is not None:  # on disk before it is kept (and before the write that may set the clock)
                    _journal_origin(durable, origin, self.clock.timebase)
                self.origin = origin
        self.due = True

    @staticmethod
    def take_origin(clock: Clock) -> ClockOrigin | None:
        """The clock's time at one of its second transitions (where it shows whole seconds), else as read."""
        timebase = clock.timebase
        plc = clock.read()
        if plc is None:
            return None
        at, width = timebase.now(), 0.0
        if clock.transition is not None:
            # it may not tick (a read-out left frozen): then its reading is all there is
            with contextlib.suppress(HilError):
                plc, at, width = clock.transition()
        return ClockOrigin(plc, at, float(getattr(timebase, "time_scale", 1.0)), width)

    # -- putting it back ------------------------------------------------------------------------------------------
    def put_back(self, exact: bool, durable: Journal | None) -> list[Failure]:
        """The clock back at its origin's offset (to within :attr:`ROUGH`, or ``exact``ly: then its origin and its
        journal entry end), or on the bench's time when it had no valid time; the failure, if any."""
        origin = self.origin
        shown = f"{origin.plc:%Y-%m-%d %H:%M:%S} at its offset" if origin is not None else "the bench's time"
        if self.clock is None:
            return [("clock", shown, NO_CLOCK)]
        self.busy = True
        try:
            self._put(self.clock, origin, exact)
        except HilError as exc:
            return [("clock", shown, str(exc))]
        finally:
            self.busy = False
        self.due = False
        if exact:
            self.origin = None
            if durable is not None:
                durable.drop_clock()
        return []

    def _put(self, clock: Clock, origin: ClockOrigin | None, exact: bool) -> None:
        if origin is None:
            clock.put(clock.timebase.calendar, exact)
        elif exact:
            self._put_exactly(clock, origin)
        else:
            clock.put(_carried(origin, clock.timebase, dt.timedelta(0)), False)

    def _put_exactly(self, clock: Clock, origin: ClockOrigin) -> None:
        """The clock back at its origin's offset, read back where its second transitions can be timed: the error
        at the next one, against the origin timed the same way (so a bias of the timing cancels).

        A set lands a PLC-specific latency after it is sent (the scans that service the write and take it into the
        chip), which only the read-back shows, with the same sign run after run: kept because it is within the
        brackets, it adds up over runs (ten runs on 2 ms scans: −25 to −35 ms, every error negative).  The first
        error is known to ± half the two brackets (each timing is its bracket's middle; the difference of two such
        uniform errors is triangular): taken off by a second set once it exceeds half of that — the second set's
        own error is then smaller on average than the one kept, while the rarer noise beyond it (a busy host's
        wide brackets) is not "corrected" into the clock.  Later errors only when they exceed the two timings'
        brackets, up to :attr:`TRIES` sets; then an error within :attr:`ROUGH` is kept (:attr:`error` says it),
        one beyond it is a HilError saying by how much."""
        shift, error, width = dt.timedelta(0), 0.0, 0.0
        for attempt in range(self.TRIES):
            clock.put(_carried(origin, clock.timebase, shift), True)
            if clock.transition is None:
                _read_back_whole_seconds(clock, origin)
                return
            shown, at, width = clock.transition()
            error = (shown - (origin.plc + dt.timedelta(seconds=at - origin.at))).total_seconds()
            self.error = error
            if abs(error) <= ((origin.width + width) / 4 if attempt == 0 else origin.width + width):
                return
            shift += dt.timedelta(seconds=error)
        if abs(error) > self.ROUGH:
            raise HilError(f"after {self.TRIES} sets the clock is {error * 1000:+.0f} ms off its original "
                           f"offset (read back at a second transition, ± {(origin.width + width) * 1000:.0f} ms)")

    # -- a dead run's clock -----------------------------------------------------------------------------------------
    def journaled_origin(self, journal: Journal, report: Recovery, by_hand: bool, accept_host_clock: bool,
                         writable: frozenset[object]) -> ClockOrigin | None:
        """The origin a dead run journaled, when it may be put back now (else None, and ``report`` says why; with
        ``report.show`` it says what a restore would set, and None)."""
        entry = journal.clock()
        if entry is None:
            return None
        why = CLOCK.check(entry) or age_problem(entry, by_hand) or self._refusal(writable)
        if why:
            report.refused.append(f"clock: {why}")
            return None
        assert self.clock is not None  # (_refusal said so otherwise)
        try:
            origin = origin_from_journal(entry, self.clock.timebase, HostClocks.now(),
                                         accept_host_clock=accept_host_clock)
        except OriginRefused as exc:  # kept in the journal: only a person can tell the right time now
            report.refused.append(f"clock (original {entry['plc']} at host time {entry['host']:.3f}): its origin is "
                                  f"refused — {exc}; not set. Set the PLC's clock by hand, then remove the "
                                  f"\"clock\" entry from {journal.path}")
            return None
        if report.show:
            report.planned.append(f"clock to {origin.original(self.clock.timebase):%Y-%m-%d %H:%M:%S} "
                                  f"({_reference(origin)})")
            return None
        return origin

    def _refusal(self, writable: frozenset[object]) -> str | None:
        if self.clock is None:
            return NO_CLOCK
        if self.clock.touches and not self.clock.touches & writable:
            return "the clock's elements are not in the profile's [safety] writable"
        return None

    def recover(self, origin: ClockOrigin, durable: Journal | None, report: Recovery) -> None:
        """Take a dead run's ``origin`` as this session's, put the clock back from it exactly, and say in ``report``
        whether it reads back so."""
        self.due, self.origin = True, origin
        failures = self.put_back(True, durable)
        if failures:
            report.failures += [f"clock (original {value}): {why}" for _, value, why in failures]
            return
        assert self.clock is not None  # (put_back failed otherwise)
        try:  # (what it shows now, for the report: put_back verified it before its journal entry went)
            got = _read_back_whole_seconds(self.clock, origin)
        except HilError as exc:
            report.failures.append(f"clock: {exc}")
        else:
            report.verified.append(f"clock = {got:%Y-%m-%d %H:%M:%S} ({_reference(origin)}, read back)")


def _read_back_whole_seconds(clock: Clock, origin: ClockOrigin) -> dt.datetime:
    """The clock read back as it is (whole seconds): it must show its origin carried to now, within two of its
    seconds — else a HilError (and, before a journal entry goes, the entry stays)."""
    want, got = origin.original(clock.timebase), clock.read()
    if got is None or abs((got - want).total_seconds()) > 2.0 * max(1.0, origin.scale):
        raise HilError(f"reads {got} after the restore, expected {want:%Y-%m-%d %H:%M:%S}")
    return got


def _reference(origin: ClockOrigin) -> str:
    """What a dead run's origin was carried on to now, for the report."""
    if not origin.host_step:
        return "its offset from host time"
    # (to the millisecond: finer would show the reading's own noise)
    return (f"carried on the host's boot clock: the wall clock was stepped by {origin.host_step:+.3f} s since, which "
            f"moves nothing")


def _carried(origin: ClockOrigin, timebase: Timebase, shift: dt.timedelta) -> Callable[[], dt.datetime]:
    """When to set the clock to: its origin carried to the moment of the set, less ``shift`` (a set's latency)."""
    return lambda: origin.original(timebase) - shift


def _journal_origin(durable: Journal, origin: ClockOrigin, timebase: Timebase) -> None:
    """The origin on disk with the host's wall clock — and what bounds the host clocks' agreement later
    (:func:`hil.bench.clock.step_bound`): the origin's bracket, the pair's spread."""
    lag = (timebase.now() - origin.at) / origin.scale  # host seconds since the origin
    host = HostClocks.now()
    durable.set_clock(origin.plc, host.wall - lag, origin.scale, boot=host.boot,
                      since_boot=None if host.since_boot is None else host.since_boot - lag,
                      width=origin.width / origin.scale, spread=host.spread)


__all__ = ["ClockKeeper"]
