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
family's link, reached through its public API only — which implements its address model — :meth:`Guard.split`
(an address → the elements it covers, the journal's keys), :meth:`Guard.read_originals` and
:meth:`Guard.write_back` — and passes the writes it guards to :meth:`Guard.guarded`.  ``str(element)`` is an
element's name in the journal; ``split(name)`` reads it back.

The guard is the one place these meet; each part is its own module: the allow-list (:mod:`hil.bench.allow`), the
journal writer (:mod:`hil.bench.write_journal`), the clock (:mod:`hil.bench.clock`,
:mod:`hil.bench.clock_keeper`), the verified put-back (:mod:`hil.bench.putback`) and recovery's decisions
(:mod:`hil.bench.recover`, :mod:`hil.bench.replay`, reported as :class:`hil.bench.recovery.Recovery`).
"""

from __future__ import annotations

import contextlib
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import AbstractContextManager
from typing import Any, Protocol, TypeVar

from hil.bench.allow import AllowList
from hil.bench.clock import ORIGIN_MAX_AGE, Clock, ClockOrigin, OriginRefused, origin_from_journal
from hil.bench.clock_keeper import ClockKeeper
from hil.bench.putback import Failure, Item, PutBack, put_back
from hil.bench.recover import RecoveryStep, Replay, recover
from hil.bench.recovery import Recovery
from hil.bench.write_journal import WriteJournal
from hil.core.errors import HilError, RestoreError
from hil.core.journal import Journal
from hil.core.link import Link
from hil.io.status import PlcStatus

T = TypeVar("T")

class Guard(ABC):
    """Mixed into a family's guarded link, before the link's own base class (it uses the link's ``_lock``)."""

    _lock: Any  # the Link's: one request on the wire at a time

    def __init__(self, description: str, writable: Iterable[Any], volatile: Iterable[Any] = ()) -> None:
        super().__init__(description)  # type: ignore[call-arg]  # the Link's (a mixin: mypy sees object's)
        self.allow = AllowList(frozenset(writable), frozenset(volatile))
        self.written = WriteJournal(self.allow.volatile)
        self.clocks = ClockKeeper()
        self.reopened = 0  # reconnections made to restore
        # What the PLC rewrites itself because of a write (e.g. an EN rising edge → PR/IR/DR of that FUN86 box):
        # journaled as originals along with the written elements, never written by the test.
        self.side_effects: Callable[[list[Any]], Iterable[Any]] | None = None
        # the journal's key is the profile's [bench] plc_id: a wire that reads no PLC identity may replay it
        self.identity_vouched = False
        # A suite's working state (:meth:`hold`): elements every test of it sets before relying on them, journaled
        # as usual but put back when the hold ends, not after each test (the clock: ``clocks.held``).
        self.held: frozenset[Any] = frozenset()

    # -- its parts, as the families and the bench hold them ---------------------------------------------------
    @property
    def writable(self) -> frozenset[Any]:
        return self.allow.writable

    @property
    def volatile(self) -> frozenset[Any]:
        return self.allow.volatile

    @property
    def journal(self) -> dict[Any, int]:
        """Element → its original, until it is put back and read back."""
        return self.written.originals

    @property
    def touched(self) -> set[Any]:
        return self.written.touched

    @property
    def last_wrote(self) -> dict[Any, int]:
        return self.written.last_wrote

    @property
    def durable(self) -> Journal | None:
        """The journal on disk (None for an in-process emulator: nothing outlives the run)."""
        return self.written.durable

    @durable.setter
    def durable(self, journal: Journal | None) -> None:
        self.written.durable = journal

    @property
    def clock(self) -> Clock | None:
        """The clock the family declares (None: the tests set none)."""
        return self.clocks.clock

    @clock.setter
    def clock(self, clock: Clock | None) -> None:
        self.clocks.clock = clock

    def causes_side_effects(self, element: Any) -> bool:
        """Whether a write of ``element`` alone makes the PLC rewrite something itself (an EN, FUN86's Sn/Zn
        registers): such causes are put back before what they make the PLC rewrite is read."""
        return self.side_effects is not None and bool(list(self.side_effects([element])))

    # -- the family's address model ---------------------------------------------------------------------------
    @abstractmethod
    def split(self, name: Any) -> list[Any]:
        """The elements a write to ``name`` covers (e.g. WM16 → M16…M31, VW100 → VB100, VB101)."""

    def keys(self, elements: list[Any]) -> list[Any]:
        """The elements to journal for a write to ``elements`` (the same, unless the wire rewrites more)."""
        return elements

    @abstractmethod
    def read_originals(self, elements: list[Any]) -> list[int]:
        """Their values now, read so that no late reply to an earlier request is taken for them."""

    @abstractmethod
    def write_back(self, items: list[Item]) -> None:
        """Write the values, straight to the link (no allow-list: these are the PLC's own originals)."""

    @abstractmethod
    def reopen(self) -> None:
        """Reconnect the wire after a failure."""

    def _restore_actions(self) -> None:  # noqa: B027 - a hook: most families have no undo of their own
        """A family's own undo that comes before the values (e.g. RUN/STOP back); journal extras cleared."""

    def value_problem(self, element: Any, value: int) -> str | None:
        """Why ``value`` cannot be ``element``'s (None when it can): the family's range check."""
        return None

    # -- the allow-list and the journal ------------------------------------------------------------------------
    def check(self, names: Iterable[Any]) -> list[Any]:
        """Raise WriteRefused unless every element is writable; return the elements covered."""
        return self.allow.check(names, self.split)

    def guarded(self, names: Iterable[Any], write: Callable[[], T], wrote: dict[Any, int] | None = None) -> T:
        """``write()`` once every element of ``names`` is allowed and its original journaled, with ``wrote`` (element
        → the value about to be written, when the family knows it) — on disk before the write goes out."""
        with self._lock:
            covered = self.check(names)
            self._remember(covered, wrote or {})
            return write()

    def setting_clock(self, action: Callable[[], T]) -> T:
        """``action()`` sets the clock by a clock function (not by writing elements): journal the clock first."""
        with self._lock:
            self.clocks.note(self.durable)
            return action()

    def _remember(self, covered: Sequence[Any], wrote: dict[Any, int]) -> None:
        """Journal the originals of ``covered`` and of what the PLC rewrites because of a write to them."""
        if self.written.replaying:  # recovery's own writes (the clock's set procedure) journal nothing
            self.written.touched.update(covered)
            return
        if self.clocks.touched_by(list(covered)):
            self.clocks.note(self.durable)
        wanted = list(covered)
        if self.side_effects is not None:
            effects = list(self.side_effects(list(covered)))
            wanted += effects
            self.written.effects.update(self.keys(effects))
        fresh = self.written.fresh(self.keys(wanted))
        originals = self._originals(fresh)
        # on disk (fsync'd) before the write goes out: the original and what is written — except the guard's own
        # clock restore once the journal has failed (a restore is never refused; it puts the PLC back)
        durable = self.durable
        self.written.record(originals, wrote, on_disk=not (self.clocks.busy and durable is not None and durable.failed))
        self.written.touch(covered, wrote)

    def _originals(self, fresh: list[Any]) -> dict[Any, int]:
        """The originals of ``fresh`` elements, about to be journaled: read from the PLC, always — a value an
        earlier restore read back is no proof of what the element holds now (a ladder or an operator may have
        written it since)."""
        return dict(zip(fresh, self.read_originals(fresh))) if fresh else {}

    # -- per test ----------------------------------------------------------------------------------------------
    def begin(self, test_id: str = "") -> None:
        """A test starts: first retry any restore that failed before (a RestoreError here means the PLC is still
        not as it was found), then forget what was touched."""
        if self.durable is not None:
            self.durable.test = test_id
        if self.written.due(self.held) or self.clocks.due_now(False):
            self.restore()
        self.start_journal()

    def hold(self, elements: Iterable[Any], clock: bool = False) -> None:
        """From now until :meth:`release`, put ``elements`` (and, with ``clock``, the clock) back when the hold
        ends instead of after each test: a suite's working state — words every one of its tests sets before it
        relies on them (a FUN86 box's operand blocks, the bench's scratch), whose values between its tests are as
        arbitrary as a bench's originals are.  Nothing else changes: each is journaled (on disk first) before its
        first write, its original kept, and put back and read back equal when the hold ends, by :meth:`finish`
        at the latest, or by recovery after a crash.  Saves, per test, the read of their originals, the write back
        and the read back (on port 0 at 9600 bit/s, most of a PID test's traffic)."""
        self.held = frozenset(self.keys(list(elements)))
        self.clocks.held = clock

    def release(self) -> list[Item]:
        """End the hold: everything journaled goes back now (:meth:`restore`), the clock too when a test set it."""
        with self._lock:
            self.held, self.clocks.held = frozenset(), False
            return self.restore()

    def end(self) -> None:
        """A test ended, pass or fail: put the PLC back.  Idempotent."""
        try:
            self.restore()
        finally:
            self.start_journal()

    def finish(self) -> None:
        """The session ends: any hold ends, the clock back exactly at its original offset, its journal entry
        cleared, and whatever is still unrestored put back or retried."""
        self.held, self.clocks.held = frozenset(), False
        try:
            self.restore(exact=True)
        finally:
            self.start_journal()

    def start_journal(self) -> None:
        """The next test starts: forget which elements were touched.  Originals whose restore failed stay in the
        journal (and on disk) until a restore succeeds — :meth:`restore` retries them."""
        self.written.forget_test()

    @property
    def unrestored(self) -> list[tuple[Any, Any]]:
        """What is still to be put back: (element, original), and the clock while it is due."""
        clock = self.clocks.pending()
        return list(self.journal.items()) + ([clock] if clock is not None else [])

    # -- restore -----------------------------------------------------------------------------------------------
    def restore(self, exact: bool = False) -> list[Item]:
        """The family's own undo, the clock, then every journaled original written back and read back equal
        (outside a hold: :meth:`hold`).

        The clock is put back when a test may have set it (and it is not held) — to within half a second, or
        ``exact``ly (then also when it is only approximately back), which ends its journal entry.  Returns the
        elements restored.  Raises RestoreError listing what could not be put back, each with its original value;
        that stays in the journal for the next restore."""
        with self._lock:
            failures: list[Failure] = []
            try:
                self._restore_actions()
            except HilError as exc:
                failures.append(("RUN/STOP and disabled bits", "as before", str(exc)))
            if self.clocks.due_now(exact):
                failures += self.clocks.put_back(exact, self.durable)
            items = self.written.due(self.held)
            done = self.put_back(items)
            self.written.verified(done.restored)
            if failures or done.failed:
                raise RestoreError(failures + done.failed)
            return items

    def put_back(self, items: list[Item]) -> PutBack:
        """Write ``items`` and read them back (:func:`hil.bench.putback.put_back`); when the wire failed, reconnect
        once and try again."""
        return put_back(self, items, self._reconnect, self._read_first(items))

    def _reconnect(self) -> None:
        self.reopen()
        self.reopened += 1

    #: a family whose wire reads a block for what it costs to write it (FATEK on port 0) reads the side effects
    #: of a test's writes before putting them back, and writes only what differs (:func:`hil.bench.putback.put_back`)
    read_effects_first = False

    def _read_first(self, items: list[Item]) -> set[Any]:
        """Journaled elements checked by a read before anything is written to them (written back only where they
        differ): the side effects of this test (OR, WR, Yn of a FUN86 box whose EN the test switched, never
        written by the test itself); a family may add more."""
        return self.written.effects_of_this_test() if self.read_effects_first else set()

    # -- recovery first ----------------------------------------------------------------------------------------
    def recover(self, steps: Iterable[RecoveryStep] = (), *, by_hand: bool = False, show: bool = False,
                accept_host_clock: bool = False) -> Recovery | None:
        """Replay what a dead run left in the durable journal (before anything else), as far as it can be proven
        (:mod:`hil.bench.recover`): the family's ``steps`` first, then its actions, the clock (exactly) and the
        elements — and the same for each journal a run's lanes left beside it (:meth:`Journal.lane_names`), each
        as if it were this run's own; a journal that cannot be read is named (refused) and the others still
        replayed.  ``show``: decide and list only, writing nothing (``hil restore --show``; the family's steps,
        which read another device, are listed unread).  ``accept_host_clock``: a clock origin from another boot
        of the host is carried on the host clock as it is (:func:`origin_from_journal`).  None without a durable
        journal (an in-process emulator: nothing outlives a run)."""
        if self.durable is None:
            return None
        how = Replay(tuple(steps), by_hand, show, accept_host_clock)
        return recover(self, how, self._recover_actions, self._lock)

    def _recover_actions(self, journal: Journal, report: Recovery, by_hand: bool) -> None:  # noqa: B027 - a hook
        """A family's own entries (e.g. RUN/STOP, disabled bits), each checked and read back, into ``report``."""


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

    def exclusive(self) -> AbstractContextManager[None]: ...


class GuardedLink(Guard, Link):
    """The guard wrapped round a link (composition): it holds the link as ``inner`` and reaches it only through
    its public API — reads pass straight through, writes go through :meth:`Guard.guarded`.  A family's guarded
    link adds its address model and the writes of its face."""

    def __init__(self, inner: PublicLink, writable: Iterable[Any], volatile: Iterable[Any] = ()) -> None:
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


# Clock, ClockOrigin, ORIGIN_MAX_AGE, OriginRefused, origin_from_journal (hil.bench.clock), Recovery
# (hil.bench.recovery) and RecoveryStep (hil.bench.recover) are named here too: families declare their clock and
# recovery steps to "the guard"
__all__ = ["ORIGIN_MAX_AGE", "Clock", "ClockOrigin", "Guard", "GuardedLink", "OriginRefused", "PublicLink",
           "Recovery", "RecoveryStep", "origin_from_journal"]
