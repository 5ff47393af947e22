"""The write guard every family's bench I/O goes through: the allow-list, the durable journal, restore, recovery.

A real PLC is somebody's machine.  The guard

* refuses any write touching an element outside the profile's ``[safety] writable`` ranges (WriteRefused,
  raised before the link sees the request);
* journals the original value of each element before its first write in a test — on disk first
  (:class:`hil.core.journal.Journal`, fsync'd) when the bench has a durable journal — together with what the PLC
  itself rewrites because of that write (:attr:`Guard.side_effects`, declared by the family's device layer);
* before the session's first write that may set the PLC's clock (:class:`Clock`, declared by the family), takes
  the clock's origin — its time at one of its second transitions, timed against the bench's monotonic reference
  (a whole-second reading alone is up to a second late) — journals it with the host's wall clock, and restores it
  at that *offset* (not to host local time): to within half a second after each test (no wait for a whole
  second), exactly when the session ends (:meth:`Guard.finish`) — both from the session's first origin, on the
  monotonic reference, so the per-test errors never add up and a host clock step moves nothing;
* :meth:`Guard.restore`: the clock, then every original written back and read back equal; an entry leaves the
  journal only once verified, a failed one stays and is retried by the next restore (reconnecting once when the
  wire failed);
* :meth:`Guard.hold`: a suite's working state — words each of its tests sets before relying on them, and the
  clock — journaled the same way but put back once, when the suite's last test ends, not after every test;
* :meth:`Guard.recover`: replays what a dead run left in the durable journal, through the same restore (the
  clock exactly, from its journaled wall-clock origin — refused, and said so, when that origin is older than
  :data:`ORIGIN_MAX_AGE`, the host clock was stepped since, or it is from another boot of the host and not
  accepted by hand: :func:`origin_from_journal`).

Elements the PLC itself rewrites every scan (``volatile``) are allowed but not journaled.

The guard knows no family: a family's guarded link is a :class:`GuardedLink` — the guard wrapped round the
family's link, reached through its public API only — which implements its address model — :meth:`Guard.split` (an address → the elements it covers, the journal's keys),
:meth:`Guard.read_originals` and :meth:`Guard.write_back` — and passes the writes it guards to
:meth:`Guard.guarded`.  ``str(element)`` is an element's name in the journal; ``split(name)`` reads it back.
"""

from __future__ import annotations

import contextlib
import datetime as dt
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, ContextManager, Protocol, TypeVar

from hil.bench.replay import Recovery, age_problem, identity_problem, replay_elements
from hil.core.errors import HilError, RestoreError, TransportError, WriteRefused
from hil.core.journal import CLOCK, COILS, Journal, JournalError, journal_path
from hil.core.link import Link
from hil.core.timebase import HostClocks, Timebase
from hil.io.status import PlcStatus

T = TypeVar("T")
Failure = tuple[str, Any, str]  # (element, original, why), as RestoreError lists them


@dataclass(frozen=True)
class Clock:
    """A clock the PLC keeps that a test may set, as the family declares it to the guard."""

    touches: frozenset  # elements a write to which may set the clock (empty: only a clock function sets it)
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
    """A journaled clock origin (PLC time at host wall time ``host``, ×``scale``) on this session's ``timebase``,
    checked against the host's clocks now: refused when it is in the future, older than :data:`ORIGIN_MAX_AGE`,
    or when the wall clock and the boot clock disagree about the time since by more than the journal's own
    measurement allows (:func:`step_bound`: NTP slews both alike, only a step parts them).  From another boot —
    or where the boot clock cannot be compared — nothing can tell a step: refused (:class:`HostClockUnproven`)
    unless ``accept_host_clock``.  Raises :class:`OriginRefused` saying which, with the figures."""
    plc, wall, scale = dt.datetime.fromisoformat(entry["plc"]), float(entry["host"]), float(entry["scale"])
    elapsed = host.wall - wall
    bound = step_bound(entry, host)
    if elapsed < -bound:
        raise OriginRefused(f"its host time is {-elapsed:.6f} s in the future: the host clock was set back since")
    if elapsed > ORIGIN_MAX_AGE:
        raise OriginRefused(f"it is {elapsed / 3600:.1f} h old (limit {ORIGIN_MAX_AGE / 3600:.0f} h): too long to "
                            f"carry its offset from host time")
    booted = entry.get("since_boot")
    if host.boot is None or entry.get("boot") != host.boot or booted is None or host.since_boot is None:
        if not accept_host_clock:
            raise HostClockUnproven(_unproven(entry, host, elapsed))
    else:
        passed = host.since_boot - float(booted)
        step = elapsed - passed
        if abs(step) > bound:
            # (to the millisecond: finer would show the reading's own noise, +42.599999 for a 42.6 s step)
            raise OriginRefused(f"the host's wall clock moved {elapsed:+.3f} s since it while its boot clock moved "
                                f"{passed:+.3f} s: the host clock was stepped by {step:+.3f} s, beyond the "
                                f"±{bound:.3f} s the journal's own measurement allows — its offset from host time "
                                f"is lost")
    return ClockOrigin(plc, timebase.now() - elapsed * scale, scale)


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


#: a family's own recovery step (e.g. a fault rig's coils): called with the journal, the report to add to and
#: whether an operator asked for it by hand (``hil restore``: older entries too)
RecoveryStep = Callable[[Journal, Recovery, bool], None]


class Guard(ABC):
    """Mixed into a family's guarded link, before the link's own base class (it uses the link's ``_lock``)."""

    _lock: Any  # the Link's: one request on the wire at a time
    CLOCK_SETS = 3  # exact clock restores tried before settling for CLOCK_ROUGH
    CLOCK_ROUGH = 0.5  # bench seconds: what the per-test restore promises, and all an exact one falls back to


    def __init__(self, description: str, writable: Iterable, volatile: Iterable = ()) -> None:
        super().__init__(description)  # type: ignore[call-arg]  # the Link's
        self.writable = frozenset(writable)
        self.volatile = frozenset(volatile)
        self.journal: dict[Any, int] = {}  # element → its value before the first write (until verified restored)
        self.touched: set = set()  # every element written since the test started
        self.effects: set = set()  # every element journaled as a side effect of those writes (``side_effects``)
        self.last_wrote: dict[Any, int] = {}  # element → what the test last wrote to it, where the family knows
        self.reopened = 0  # reconnections made to restore
        # On disk before each write goes out (None for an in-process emulator: nothing outlives the run).
        self.durable: Journal | None = None
        # What the PLC rewrites itself because of a write (e.g. an EN rising edge → PR/IR/DR of that FUN86 box):
        # journaled as originals along with the written elements, never written by the test.
        self.side_effects: Callable[[list], Iterable] | None = None
        self.clock: Clock | None = None
        # the clock before the session's (or a dead run's) first write that may set it; kept, and journaled,
        # until the session's end puts it back exactly
        self.clock_origin: ClockOrigin | None = None
        self.clock_due = False  # a test may have set the clock and it is not put back yet
        self._clock_busy = False  # the guard is reading or putting back the clock itself
        self.clock_error: float | None = None  # seconds the last exact put left it off, read back (None: not read)
        # the journal's key is the profile's [bench] plc_id: a wire that reads no PLC identity may replay it
        self.identity_vouched = False
        self._replaying = False  # recovery is writing a dead run's originals back (not a test writing)
        # A suite's working state (:meth:`hold`): elements every test of it sets before relying on them, journaled
        # as usual but put back when the hold ends, not after each test; ``clock_held`` the same for the clock.
        self.held: frozenset = frozenset()
        self.clock_held = False

    def causes_side_effects(self, element: Any) -> bool:
        """Whether a write of ``element`` alone makes the PLC rewrite something itself (an EN, FUN86's Sn/Zn
        registers): such causes are put back before what they make the PLC rewrite is read."""
        return self.side_effects is not None and bool(list(self.side_effects([element])))

    # -- the family's address model ---------------------------------------------------------------------------
    @abstractmethod
    def split(self, name: Any) -> list:
        """The elements a write to ``name`` covers (e.g. WM16 → M16…M31, VW100 → VB100, VB101)."""

    def keys(self, elements: list) -> list:
        """The elements to journal for a write to ``elements`` (the same, unless the wire rewrites more)."""
        return elements

    @abstractmethod
    def read_originals(self, elements: list) -> list[int]:
        """Their values now, read so that no late reply to an earlier request is taken for them."""

    @abstractmethod
    def write_back(self, items: list[tuple[Any, int]]) -> None:
        """Write the values, straight to the link (no allow-list: these are the PLC's own originals)."""

    @abstractmethod
    def reopen(self) -> None:
        """Reconnect the wire after a failure."""

    def _restore_actions(self) -> None:
        """A family's own undo that comes before the values (e.g. RUN/STOP back); journal extras cleared."""

    # -- the allow-list and the journal ------------------------------------------------------------------------
    def check(self, names: Iterable[Any]) -> list:
        """Raise WriteRefused unless every element is writable; return the elements covered."""
        covered: list = []
        for name in names:
            parts = self.split(name)
            refused = [str(p) for p in parts if p not in self.writable]
            if refused:
                shown = ", ".join(refused[:4]) + ("…" if len(refused) > 4 else "")
                raise WriteRefused(
                    f"write to {name} refused: {shown} not in the bench's [safety] writable list — add the "
                    f"range to the profile if this test may change it on this bench")
            covered += parts
        return covered

    def guarded(self, names: Iterable[Any], write: Callable[[], T], wrote: dict | None = None) -> T:
        """``write()`` once every element of ``names`` is allowed and its original journaled, with ``wrote`` (element
        → the value about to be written, when the family knows it) — on disk before the write goes out."""
        with self._lock:
            covered = self.check(names)
            self._remember(covered, wrote or {})
            return write()

    def setting_clock(self, action: Callable[[], T]) -> T:
        """``action()`` sets the clock by a clock function (not by writing elements): journal the clock first."""
        with self._lock:
            self._note_clock()
            return action()

    def _remember(self, covered: Sequence, wrote: dict) -> None:
        if self._replaying:  # recovery's own writes (the clock's set procedure) put back, they journal nothing
            self.touched.update(covered)
            return
        if self.clock is not None and self.clock.touches.intersection(covered):
            self._note_clock()
        wanted = list(covered)
        if self.side_effects is not None:
            effects = list(self.side_effects(list(covered)))
            wanted += effects
            self.effects.update(self.keys(effects))
        fresh = [e for e in dict.fromkeys(self.keys(wanted)) if e not in self.journal and e not in self.volatile]
        originals = self._originals(fresh)
        # on disk (fsync'd) before the write goes out: the original and what is written — except the guard's own
        # clock restore once the journal has failed (a restore is never refused; it puts the PLC back)
        if self.durable is not None and not (self._clock_busy and self.durable.failed):
            self.durable.add_elements({str(e): v for e, v in originals.items()},
                                      {str(e): v for e, v in wrote.items() if e not in self.volatile})
        self.journal.update(originals)
        self.touched.update(covered)
        for element in covered:
            if element in wrote:
                self.last_wrote[element] = wrote[element]
            else:
                self.last_wrote.pop(element, None)

    def _originals(self, fresh: list) -> dict:
        """The originals of ``fresh`` elements, about to be journaled: read from the PLC, always — a value an
        earlier restore read back is no proof of what the element holds now (a ladder or an operator may have
        written it since)."""
        return dict(zip(fresh, self.read_originals(fresh))) if fresh else {}

    def _note_clock(self) -> None:
        """Before the first write that may set the clock: its origin, durable first."""
        if self._clock_busy:
            return
        if self.clock_origin is not None or self.clock is None:
            self.clock_due = True
            return
        self._clock_busy = True
        try:
            origin = self._take_origin(self.clock)
        finally:
            self._clock_busy = False
        if origin is None:  # no valid time: there is no offset to keep; the restore puts it on the bench's time
            self.clock_due = True
            return
        if self.durable is not None:  # on disk before it is kept (and before the write that may set the clock)
            timebase = self.clock.timebase
            lag = (timebase.now() - origin.at) / origin.scale  # host seconds since the origin
            host = HostClocks.now()
            # with what bounds the host clocks' agreement later (step_bound): the origin's bracket, the pair's spread
            self.durable.set_clock(origin.plc, host.wall - lag, origin.scale, boot=host.boot,
                                   since_boot=None if host.since_boot is None else host.since_boot - lag,
                                   width=origin.width / origin.scale, spread=host.spread)
        self.clock_origin = origin
        self.clock_due = True

    @staticmethod
    def _take_origin(clock: Clock) -> ClockOrigin | None:
        """The clock's time at one of its second transitions (where it shows whole seconds), else as read."""
        timebase = clock.timebase
        plc = clock.read()
        if plc is None:
            return None
        at, width = timebase.now(), 0.0
        if clock.transition is not None:
            try:
                plc, at, width = clock.transition()
            except HilError:  # it does not tick (a read-out left frozen): its reading is all there is
                pass
        return ClockOrigin(plc, at, float(getattr(timebase, "time_scale", 1.0)), width)

    # -- per test ----------------------------------------------------------------------------------------------
    def begin(self, test_id: str = "") -> None:
        """A test starts: first retry any restore that failed before (a RestoreError here means the PLC is still
        not as it was found), then forget what was touched."""
        if self.durable is not None:
            self.durable.test = test_id
        if self._due_items() or self._clock_due_now(False):
            self.restore()
        self.start_journal()

    # -- a suite's working state ---------------------------------------------------------------------------------
    def hold(self, elements: Iterable[Any], clock: bool = False) -> None:
        """From now until :meth:`release`, put ``elements`` (and, with ``clock``, the clock) back when the hold
        ends instead of after each test: a suite's working state — words every one of its tests sets before it
        relies on them (a FUN86 box's operand blocks, the bench's scratch), whose values between its tests are as
        arbitrary as a bench's originals are.  Nothing else changes: each is journaled (on disk first) before its
        first write, its original kept, and put back and read back equal when the hold ends, by :meth:`finish`
        at the latest, or by recovery after a crash.  Saves, per test, the read of their originals, the write back
        and the read back (on port 0 at 9600 bit/s, most of a PID test's traffic)."""
        self.held = frozenset(self.keys(list(elements)))
        self.clock_held = clock

    def release(self) -> list[tuple[Any, int]]:
        """End the hold: everything journaled goes back now (:meth:`restore`), the clock too when a test set it."""
        with self._lock:
            self.held, self.clock_held = frozenset(), False
            return self.restore()

    def _due_items(self) -> list[tuple[Any, int]]:
        """The journaled originals to put back now: every one outside the hold."""
        return [(e, v) for e, v in self.journal.items() if e not in self.held]

    def _clock_due_now(self, exact: bool) -> bool:
        return (self.clock_due and not self.clock_held) or (exact and self.clock_origin is not None)

    def end(self) -> None:
        """A test ended, pass or fail: put the PLC back.  Idempotent."""
        try:
            self.restore()
        finally:
            self.start_journal()

    def finish(self) -> None:
        """The session ends: any hold ends, the clock back exactly at its original offset, its journal entry
        cleared, and whatever is still unrestored put back or retried."""
        self.held, self.clock_held = frozenset(), False
        try:
            self.restore(exact=True)
        finally:
            self.start_journal()

    def start_journal(self) -> None:
        """The next test starts: forget which elements were touched.  Originals whose restore failed stay in the
        journal (and on disk) until a restore succeeds — :meth:`restore` retries them."""
        self.touched.clear()
        self.effects.clear()
        self.last_wrote.clear()

    @property
    def unrestored(self) -> list[tuple[Any, Any]]:
        """What is still to be put back: (element, original), and the clock while it is due."""
        out: list[tuple[Any, Any]] = list(self.journal.items())
        if self.clock_due:
            origin = self.clock_origin
            out.append(("clock", f"{origin.plc:%Y-%m-%d %H:%M:%S}, kept at its offset from the bench's time"
                        if origin is not None else "on the bench's time"))
        return out

    # -- restore -----------------------------------------------------------------------------------------------
    def restore(self, exact: bool = False) -> list[tuple[Any, int]]:
        """The family's own undo, the clock, then every journaled original written back and read back equal
        (outside a hold: :meth:`hold`).

        The clock is put back when a test may have set it (and it is not held) — to within half a second, or
        ``exact``ly (then also when it is only approximately back), which ends its journal entry.  Returns the elements restored.
        Raises RestoreError listing what could not be put back, each with its original value; that stays in the
        journal for the next restore."""
        with self._lock:
            failures: list[Failure] = []
            try:
                self._restore_actions()
            except HilError as exc:
                failures.append(("RUN/STOP and disabled bits", "as before", str(exc)))
            if self._clock_due_now(exact):
                failures += self._put_clock(exact)
            items = self._due_items()
            bad = self._put_back(items) if items else []
            failed = {str(name) for name, _, _ in bad}
            good = [(e, v) for e, v in items if str(e) not in failed]
            for element, _ in good:
                del self.journal[element]
            if self.durable is not None and good:  # verified: only now may the originals leave the disk
                self.durable.drop_elements(str(e) for e, _ in good)
            if failures or bad:
                raise RestoreError(failures + bad)
            return items

    def _put_clock(self, exact: bool) -> list[Failure]:
        origin = self.clock_origin
        shown = f"{origin.plc:%Y-%m-%d %H:%M:%S} at its offset" if origin is not None else "the bench's time"
        if self.clock is None:
            return [("clock", shown, "this bench has no way to set the clock")]
        timebase = self.clock.timebase
        self._clock_busy = True
        try:
            if exact and origin is not None:
                self._put_exactly(origin)
            else:
                self.clock.put((lambda: origin.original(timebase)) if origin is not None else timebase.calendar,
                               exact)
        except HilError as exc:
            return [("clock", shown, str(exc))]
        finally:
            self._clock_busy = False
        self.clock_due = False
        if exact:
            self.clock_origin = None
            if self.durable is not None:
                self.durable.drop_clock()
        return []

    def _put_exactly(self, origin: ClockOrigin) -> None:
        """The clock back at its origin's offset, read back where its second transitions can be timed: the error
        at the next one, against the origin timed the same way (so a bias of the timing cancels).

        A set lands a PLC-specific latency after it is sent (the scans that service the write and take it into the
        chip), which only the read-back shows, with the same sign run after run: kept because it is within the
        brackets, it adds up over runs (ten runs on 2 ms scans: −25 to −35 ms, every error negative).  The first
        error is known to ± half the two brackets (each timing is its bracket's middle; the difference of two such
        uniform errors is triangular): taken off by a second set once it exceeds half of that — the second set's
        own error is then smaller on average than the one kept, while the rarer noise beyond it (a busy host's
        wide brackets) is not "corrected" into the clock.  Later errors only when they exceed the two timings'
        brackets, up to :attr:`CLOCK_SETS` sets; then an error within :attr:`CLOCK_ROUGH` is kept
        (:attr:`clock_error` says it), one beyond it is a HilError saying by how much."""
        clock, timebase = self.clock, self.clock.timebase
        assert clock is not None
        shift = dt.timedelta(0)
        for attempt in range(self.CLOCK_SETS):
            clock.put(lambda: origin.original(timebase) - shift, True)
            if clock.transition is None:
                return
            shown, at, width = clock.transition()
            error = (shown - (origin.plc + dt.timedelta(seconds=at - origin.at))).total_seconds()
            self.clock_error = error
            if abs(error) <= ((origin.width + width) / 4 if attempt == 0 else origin.width + width):
                return
            shift += dt.timedelta(seconds=error)
        if abs(error) > self.CLOCK_ROUGH:
            raise HilError(f"after {self.CLOCK_SETS} sets the clock is {error * 1000:+.0f} ms off its original "
                           f"offset (read back at a second transition, ± {(origin.width + width) * 1000:.0f} ms)")

    def _put_back(self, items: list[tuple[Any, int]]) -> list[Failure]:
        """Write ``items`` and read them back; when the wire failed, reconnect once and try again."""
        failures, wire_failed = self._put_back_once(items)
        if failures and wire_failed:
            try:
                self.reopen()
            except HilError as exc:
                return [(a, v, f"{why}; reconnecting failed: {exc}") for a, v, why in failures]
            self.reopened += 1
            failures, _ = self._put_back_once(items)
        return failures

    #: a family whose wire reads a block for what it costs to write it (FATEK on port 0) reads the side effects
    #: of a test's writes before putting them back, and writes only what differs (see _put_back_once)
    read_effects_first = False

    def _effects_of_this_test(self) -> set:
        """Journaled elements the PLC rewrites only because of this test's writes (e.g. OR, WR, Yn of a FUN86 box
        whose EN the test switched), never written by the test itself."""
        return self.effects - self.touched if self.read_effects_first and self.touched else set()

    def _read_first(self, items: list[tuple[Any, int]]) -> set:
        """Journaled elements checked by a read before anything is written to them (written back only where they
        differ): the side effects of this test (:meth:`_effects_of_this_test`); a family may add more."""
        return self._effects_of_this_test()

    def _put_back_once(self, items: list[tuple[Any, int]]) -> tuple[list[Failure], bool]:
        # What the test wrote goes back first, in order (an EN back at 0 stops FUN86 rewriting its outputs).  Then
        # one read is both that write's read-back and the check of what is read first (_read_first: what the PLC
        # rewrote only because of the test's writes, stable now that its cause is undone): those are written back,
        # and read back again, only where they differ — on port 0 a read of a block costs what writing it does, so
        # an untouched block costs one read instead of a write and a read-back.
        checked = self._read_first(items)
        first = [(a, v) for a, v in items if a not in checked]
        later = [(a, v) for a, v in items if a in checked]
        try:
            if first:
                self.write_back(first)
        except Exception as exc:  # noqa: BLE001 - any failure must end up in the list, not hide the rest
            return [(str(a), v, f"write failed: {exc}") for a, v in items], isinstance(exc, TransportError)
        try:
            now = self.read_originals([a for a, _ in first + later])
        except Exception as exc:  # noqa: BLE001
            return [(str(a), v, f"read-back failed: {exc}") for a, v in items], isinstance(exc, TransportError)
        wrong = [(str(a), v, f"reads {got} after restore") for (a, v), got in zip(first, now) if got != v]
        differ = [(a, v) for (a, v), got in zip(later, now[len(first):]) if got != v]
        if not differ:
            return wrong, False
        try:
            self.write_back(differ)
        except Exception as exc:  # noqa: BLE001
            return wrong + [(str(a), v, f"write failed: {exc}") for a, v in differ], isinstance(exc, TransportError)
        try:
            again = self.read_originals([a for a, _ in differ])
        except Exception as exc:  # noqa: BLE001
            return wrong + [(str(a), v, f"read-back failed: {exc}") for a, v in differ], \
                isinstance(exc, TransportError)
        return wrong + [(str(a), v, f"reads {got} after restore") for (a, v), got in zip(differ, again)
                        if got != v], False

    # -- recovery first ----------------------------------------------------------------------------------------
    def recover(self, steps: Iterable[RecoveryStep] = (), *, by_hand: bool = False, show: bool = False,
                accept_host_clock: bool = False) -> Recovery | None:
        """Replay what a dead run left in the durable journal (before anything else), as far as it can be proven
        (:mod:`hil.bench.replay`): the family's ``steps`` first, then its actions, the clock (exactly) and the
        elements — and the same for each journal a run's lanes left beside it (:meth:`Journal.lane_names`), each
        as if it were this run's own; a journal that cannot be read is named (refused) and the others still
        replayed.  ``show``: decide and list only, writing nothing (``hil restore --show``; the family's steps,
        which read another device, are listed unread).  ``accept_host_clock``: a clock origin from another boot
        of the host is carried on the host clock as it is (:func:`origin_from_journal`).  None without a durable
        journal (an in-process emulator: nothing outlives a run)."""
        journal = self.durable
        if journal is None:
            return None
        steps = tuple(steps)
        report = Recovery(journal.key, str(journal.path), show=show)
        report.merge(self._recover_journal(journal, steps, by_hand, show, accept_host_clock))
        for name in journal.lane_names():
            try:
                lane = journal.lane_journal(name)
            except JournalError as exc:  # damaged or untrusted: named, kept, and the others still replayed
                report.merge(Recovery(journal.key, str(journal_path(journal.key, journal.path.parent, name)),
                                      refused=[str(exc)], show=show))
                continue
            self.durable = lane  # what the replay drops, it drops from the lane's file
            try:
                report.merge(self._recover_journal(lane, steps, by_hand, show, accept_host_clock))
            finally:
                self.durable = journal
        return report

    def _recover_journal(self, journal: Journal, steps: tuple[RecoveryStep, ...], by_hand: bool, show: bool,
                         accept_host_clock: bool) -> Recovery:
        try:
            journal.data = journal.load()
        except JournalError as exc:
            return Recovery(journal.key, str(journal.path), refused=[str(exc)], show=show)
        report = Recovery(journal.key, str(journal.path), journal.describe(), by=journal.left_by(), show=show)
        if not journal.pending:
            return report
        mismatch = identity_problem(journal, self.identity_vouched)
        if mismatch:
            report.refused.append(mismatch)
            return report
        if show:  # a family's step reads (and writes) another device: listed as the journal holds it
            report.planned += [f"{line} (not read by --show)" for line in journal.describe(COILS)]
        else:
            for step in steps:
                step(journal, report, by_hand)
        with self._lock:
            try:
                self._recover_actions(journal, report, by_hand)
            except HilError as exc:
                report.failures.append(f"RUN/STOP and disabled bits: {exc}")
            self._recover_clock(journal, report, by_hand, accept_host_clock)
            replay_elements(self, journal, report, by_hand)
        return report

    def _recover_actions(self, journal: Journal, report: Recovery, by_hand: bool) -> None:
        """A family's own entries (e.g. RUN/STOP, disabled bits), each checked and read back, into ``report``."""

    def _recover_clock(self, journal: Journal, report: Recovery, by_hand: bool, accept_host_clock: bool) -> None:
        """The clock a dead run may have set, back at its offset from the host's clock (exactly)."""
        entry = journal.clock()
        if entry is None:
            return
        why = CLOCK.check(entry) or age_problem(entry, by_hand)
        if why is None and self.clock is None:
            why = "this bench has no way to set the clock"
        elif why is None and self.clock.touches and not self.clock.touches & self.writable:
            why = "the clock's elements are not in the profile's [safety] writable"
        if why:
            report.refused.append(f"clock: {why}")
            return
        try:
            origin = origin_from_journal(entry, self.clock.timebase, HostClocks.now(),
                                         accept_host_clock=accept_host_clock)
        except OriginRefused as exc:  # kept in the journal: only a person can tell the right time now
            report.refused.append(f"clock (original {entry['plc']} at host time {entry['host']:.3f}): its origin is "
                                  f"refused — {exc}; not set. Set the PLC's clock by hand, then remove the "
                                  f"\"clock\" entry from {journal.path}")
            return
        if report.show:
            report.planned.append(f"clock to {origin.original(self.clock.timebase):%Y-%m-%d %H:%M:%S} (its offset "
                                  f"from host time)")
            return
        self.clock_due = True
        self.clock_origin = origin
        self._replaying = True
        try:
            failures = self._put_clock(exact=True)
        finally:
            self._replaying = False
        if failures:
            report.failures += [f"clock (original {value}): {why}" for _, value, why in failures]
            return
        want, got = origin.original(self.clock.timebase), self.clock.read()  # read back: whole seconds
        if got is None or abs((got - want).total_seconds()) > 2.0 * max(1.0, origin.scale):
            report.failures.append(f"clock: reads {got} after the restore, expected {want:%Y-%m-%d %H:%M:%S}")
        else:
            report.verified.append(f"clock = {got:%Y-%m-%d %H:%M:%S} (its offset from host time, read back)")

    def value_problem(self, element: Any, value: int) -> str | None:
        """Why ``value`` cannot be ``element``'s (None when it can): the family's range check."""
        return None


class PublicLink(Protocol):
    """What the guard uses of the link it wraps: its public API, nothing private."""

    @property
    def description(self) -> str: ...

    @property
    def requests(self) -> int: ...

    @property
    def emulator(self) -> Any: ...

    def status(self) -> PlcStatus: ...

    def unreachable_reason(self, name: Any) -> str | None: ...

    def budget(self, write: bool = False) -> float | None: ...

    def reopen(self) -> None: ...

    def close(self) -> None: ...

    def exclusive(self) -> ContextManager[None]: ...


class GuardedLink(Guard, Link):
    """The guard wrapped round a link (composition): it holds the link as ``inner`` and reaches it only through
    its public API — reads pass straight through, writes go through :meth:`Guard.guarded`.  A family's guarded
    link adds its address model and the writes of its face."""

    def __init__(self, inner: PublicLink, writable: Iterable, volatile: Iterable = ()) -> None:
        super().__init__(f"guarded {inner.description}", writable, volatile)
        self.inner = inner

    # requests are counted by the link that sends them (Link.__init__'s 0 is ignored)
    requests = property(lambda self: self.inner.requests, lambda self, value: None)
    emulator = property(lambda self: self.inner.emulator)

    def status(self) -> PlcStatus:
        return self.inner.status()

    def unreachable_reason(self, name: Any) -> str | None:
        return self.inner.unreachable_reason(name)

    def budget(self, write: bool = False) -> float | None:
        return self.inner.budget(write)

    def reopen(self) -> None:
        self.inner.reopen()

    @contextlib.contextmanager
    def exclusive(self) -> Iterator[None]:
        """The guard's and the link's lock (the link's is the one a shared line's other lanes wait on)."""
        with self._lock, self.inner.exclusive():
            yield

    def _close(self) -> None:
        self.inner.close()


__all__ = ["Clock", "ClockOrigin", "Guard", "GuardedLink", "ORIGIN_MAX_AGE", "OriginRefused", "PublicLink", "Recovery",
           "RecoveryStep", "origin_from_journal"]
