"""What every bench does the same way, whichever controller family it serves (FBs, S7-200 SMART)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from typing import Any, Generic, Protocol, TypeVar

from hil.bench.guard import GuardedLink
from hil.bench.profile import Profile
from hil.bench.recover import RecoveryStep
from hil.bench.recovery import Recovery
from hil.core.errors import HilError
from hil.core.evidence import Expectation, expect
from hil.core.journal import Journal
from hil.core.lock import lock_key, plc_key
from hil.core.signals import shielded
from hil.core.timebase import Timebase
from hil.io.url import Target


class RawLink(Protocol):
    """What the bench itself needs of its unguarded link (suites never see it)."""

    emulator: Any  # the in-process emulator (None on a wire): the family's own type
    description: str

    def reopen(self) -> None: ...

    def unreachable_reason(self, name: Any) -> str | None: ...


class SettlingPlc(Protocol):
    """What the bench itself needs of its family's PLC object."""

    def settle(self) -> None: ...


PlcT = TypeVar("PlcT", bound=SettlingPlc)
LinkT = TypeVar("LinkT", bound=RawLink)


class BenchBase(Generic[PlcT, LinkT]):
    """Subclasses set ``profile``, ``target``, ``raw`` (the unguarded link, with ``.emulator``: ``LinkT``), ``io``
    (the family's guarded link, a :class:`~hil.bench.guard.GuardedLink`), ``time`` and ``plc`` (the family's PLC
    object: ``PlcT``).  What a suite sees of it is its ``FACE`` (:mod:`hil.bench.faces`, :mod:`hil.bench.view`)."""

    profile: Profile
    target: Target
    raw: LinkT
    io: GuardedLink
    time: Timebase
    plc: PlcT
    journal: Journal | None = None
    #: the lane this bench is one of, in a run with lanes (:mod:`hil.plugin.lanes`); None: the run's only one
    lane: str | None = None
    #: the family's own recovery steps, run before the guard's (e.g. a fault rig's coils)
    recovery_steps: tuple[RecoveryStep, ...] = ()

    @property
    def name(self) -> str:
        return self.profile.name

    @property
    def is_emulator(self) -> bool:
        """True when the PLC is the in-process emulator (virtual time, direct fault injection)."""
        return self.raw.emulator is not None

    def identity(self) -> dict[str, str]:
        """What the family adds to the PLC's identity in reports (e.g. an FBs's RTC chip); never raises."""
        return {}

    def close(self) -> None:
        """Close the guarded link (a family closes what else it opened, e.g. its fault rig, first)."""
        self.io.close()

    def finish(self) -> None:
        """The session ends: put back exactly what was put back only approximately after each test (the clock's
        phase).  Raises :class:`hil.core.errors.RestoreError` when the PLC refuses."""
        self.io.finish()

    def wait(self, seconds: float) -> None:
        """Let bench time pass: sleep on a real PLC (÷ time_scale), advance virtual time on the emulator."""
        self.time.wait(seconds)

    def settle(self) -> None:
        """Make sure the PLC has completed whole scans since the last write."""
        self.plc.settle()

    def expect(self, what: str, condition: Callable[[], bool]) -> Expectation:
        """Before a stimulus: the wait for ``condition`` after it (:mod:`hil.core.evidence`); StaleEvidence now
        if it already holds."""
        return expect(self.time, what, condition)

    def exclusive(self) -> AbstractContextManager[None]:
        """Hold the wire across several requests (no other lane's between them:
        :meth:`hil.core.link.Link.exclusive`)."""
        return self.io.exclusive()

    # -- safety (issue 15): the durable journal, recovery first, the per-test restore ---------------------------
    def attach_journal(self) -> Journal | None:
        """The PLC's journal on disk, given to the guard (None for an in-process emulator: each run builds its
        own, nothing outlives the run).  Keyed by the PLC (:func:`hil.core.lock.plc_key`), it records the endpoint
        and the identity the wire reads (:meth:`plc_identity`), which recovery checks before replaying."""
        if self.target.in_process:
            return None
        self.io.identity_vouched = bool(self.profile.plc_id)
        self.io.durable = Journal(plc_key(str(self.target), self.profile.plc_id), endpoint=lock_key(str(self.target)),
                                  plc=self.plc_identity(), lane=self.lane)
        return self.io.durable

    def plc_identity(self) -> dict[str, str] | None:
        """Which PLC the wire reaches, as far as it can tell (None: it cannot); the family's."""
        return None

    def recover(self, *, by_hand: bool = False, show: bool = False,
                accept_host_clock: bool = False) -> Recovery | None:
        """Replay what a dead run left in this PLC's journal — before anything else, with the lock held (``show``:
        only say what it would do; :meth:`hil.bench.guard.Guard.recover`)."""
        return self.io.recover(self.recovery_steps, by_hand=by_hand, show=show, accept_host_clock=accept_host_clock)

    # -- a suite's working state (hil.plugin.working_state) ---------------------------------------------------
    def working_state(self, kinds: Sequence[str]) -> tuple[list, bool]:
        """The elements ``kinds`` name on this bench, and whether the clock is among them: ``"clock"`` here, the
        rest the family's (:meth:`working_elements`).  HilError for a kind the family does not know."""
        elements: list = []
        for kind in kinds:
            if kind != "clock":
                elements += self.working_elements(kind)
        return elements, "clock" in kinds

    def working_elements(self, kind: str) -> list:
        """The elements a working-state kind names (the family's); HilError for one it does not know."""
        raise HilError(f"working_state({kind!r}): this bench's family knows no such working state (only 'clock')")

    def hold(self, kinds: Sequence[str]) -> None:
        """Put back what ``kinds`` name when :meth:`release` comes, not after each test
        (:meth:`hil.bench.guard.Guard.hold`)."""
        elements, clock = self.working_state(kinds)
        self.io.hold(elements, clock)

    def release(self) -> None:
        """End the hold: what it kept goes back now, verified (shielded, as :meth:`end_test`)."""
        with shielded():
            self.io.release()

    def begin_test(self, test_id: str = "") -> None:
        """A test starts: first retry any restore that failed before, then start its journal."""
        self.io.begin(test_id)

    def end_test(self) -> None:
        """Put the PLC back as it was found: injected faults first (a plc-bit injector's own writes are then
        restored and verified with the rest), then the guard's restore (the clock, then every value written, each
        verified).  Idempotent: a second call finds nothing left to undo.  Shielded, for every caller (the bench
        fixture's teardown, a suite's own fixture, the session's end): a SIGTERM/SIGHUP/Ctrl-C that arrives
        meanwhile waits for the restore to finish, then stops the run."""
        with shielded():
            try:
                self.undo_faults()
            finally:
                self.io.end()

    def undo_faults(self) -> None:
        """Undo what the family's fault injectors did in this test (a family without injectors has nothing)."""

    def reopen(self) -> None:
        """Reconnect the wire after a failure (an emulator's server keeps running; only the client reconnects)."""
        self.raw.reopen()

    def alive(self) -> str | None:
        """None when the PLC answers (reconnecting once if needed), else why not."""
        try:
            self.io.status()
            return None
        except Exception as first:  # noqa: BLE001 - any failure here means "not answering"
            try:
                self.raw.reopen()
                self.io.status()
                return None
            except Exception as exc:  # noqa: BLE001
                return f"{first}; reconnecting: {exc}"
