"""What a test sees of a bench, as Protocols: the types a checker and an IDE know, and the list of names the
guard-enforcing proxy (:mod:`hil.bench.view`) lets through.

A Protocol here is the whole contract: a member that is not declared on it is not on the proxy, so an attribute a
test must not reach (the unguarded link, the guard's journal, a transport's private ``_write_*``) cannot be reached
through the ``bench`` fixture.  A family extends these with its own areas (``hil.families.fbs.faces``).  Members a
bench may lack (``power_cycle``, ``settings``, ``faults``) are left off the proxy of a bench that lacks them.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from hil.bench.profile import Profile
    from hil.core.evidence import Expectation
    from hil.io.url import Target


class BenchTime(Protocol):
    """The bench's time (``bench.time``): virtual on the in-process emulator, the host's clocks otherwise."""

    def now(self) -> float:
        """Bench seconds (monotonic): differences measure elapsed bench time."""
        ...

    def calendar(self) -> dt.datetime:
        """The calendar time (naive, local) an RTC in sync with this bench shows now.  On the in-process emulator
        it is the session's start plus virtual seconds — compare a PLC's clock with this, never with
        ``datetime.now()``, which a ``bench.wait(3600)`` in virtual time does not move."""
        ...

    def wait(self, seconds: float) -> None:
        """Let ``seconds`` of bench time pass (see :meth:`BenchView.wait`)."""
        ...

    @property
    def virtual(self) -> bool:
        """True when time is simulated: waiting costs no wall time."""
        ...


class PlcIO(Protocol):
    """The PLC's I/O as a test holds it (``bench.plc.io``): reads, and writes through the guard.  Every write is
    checked against the profile's ``[safety] writable`` before a byte is sent (``WriteRefused`` otherwise), the
    original is journaled first, and it is put back and read back when the test ends, pass or fail.

    Element names are the family's (FBs ``"R100"``, ``"M1952"``, ``"WM16"``, ``"DR0"``; S7 ``"VB100"``, ``"Q0.0"``)."""

    @property
    def description(self) -> str:
        """What this link reaches, as reports name it (e.g. ``guarded fatek+tcp://10.0.0.5:500``)."""
        ...

    def read(self, name: Any) -> int:
        """One element's value (a word 0–65535, a 32-bit pair, or a bit 0/1)."""
        ...

    def write(self, name: Any, value: int) -> None:
        """Write one element through the guard (journaled, restored after the test)."""
        ...

    def unreachable_reason(self, name: Any) -> str | None:
        """Why this wire cannot reach ``name`` (e.g. D4054 over the default Modbus map); None when it can."""
        ...


class FaultInjector(Protocol):
    """One of the bench's fault injectors (``bench.faults.get("heater_open")``): a relay module on a real bench, the
    emulator's plant in process.  Every fault injected is repaired when the test ends, before the guard's restore."""

    @property
    def kind(self) -> str:
        """How it injects: ``"emulator"`` (in process), ``"modbus-coil"`` (a relay module), ``"plc-bit"``,
        ``"manual"`` (a person, asked at the console)."""
        ...

    def inject(self, point: int) -> None:
        """Put the fault on ``point`` (a temperature point number, 0–31)."""
        ...

    def clear(self, point: int) -> None:
        """Take the fault off ``point`` again."""
        ...

    def open(self, point: int) -> None:
        """Open ``point``'s circuit (a sensor break: the PLC sees it at the point's next measurement)."""
        ...

    def repair(self, point: int) -> None:
        """Close ``point``'s circuit again."""
        ...

    def openable(self, points: list[int]) -> list[int]:
        """Which of ``points`` this injector can reach (a rig's allow-list or a person's hands may say fewer)."""
        ...


class Faults(Protocol):
    """The bench's fault injectors, by the names of the profile's ``[faults.<name>]`` sections."""

    def get(self, name: str) -> FaultInjector | None:
        """The injector the profile declares as ``[faults.<name>]``, or None."""
        ...

    def unavailable(self, name: str) -> str | None:
        """Why ``name`` cannot be injected on this bench (a test skips with it); None when it can."""
        ...


class BenchView(Protocol):
    """The ``bench`` fixture: the PLC under test behind its guard, the bench's time, and what the profile says.

    Family-neutral; a family's own face adds its PLC's areas (``hil.api.Bench`` for an FBs)."""

    @property
    def plc(self) -> Any:
        """The PLC object of the bench's family (``hil.api.Plc`` for an FBs)."""
        ...

    @property
    def profile(self) -> Profile:
        """The bench profile (TOML) this run uses: ``profile.name``, ``profile.path``, ``profile.safety`` …"""
        ...

    @property
    def time(self) -> BenchTime:
        """The bench's time: ``time.now()`` in bench seconds, ``time.calendar()`` for an RTC to match."""
        ...

    @property
    def target(self) -> Target:
        """The target URL the bench reaches, parsed (``str(bench.target)`` gives it back)."""
        ...

    @property
    def name(self) -> str:
        """The profile's ``[bench] name``."""
        ...

    @property
    def is_emulator(self) -> bool:
        """True for the in-process emulator (virtual time, direct fault injection), False on a wire."""
        ...

    @property
    def allow_destructive(self) -> bool:
        """True when RUN/STOP and output changes are allowed (``--hil-allow-destructive`` or the profile)."""
        ...

    def wait(self, seconds: float) -> None:
        """Let ``seconds`` of bench time pass: a sleep on a real PLC (divided by the profile's ``time_scale``
        for an accelerated external emulator), an instant jump of virtual time on the in-process emulator."""
        ...

    def settle(self) -> None:
        """Make sure the PLC has completed whole scans since the last write (its ladder has seen the write)."""
        ...

    def expect(self, what: str, condition: Callable[[], bool]) -> Expectation:
        """Before a stimulus, the wait for what it should produce: ``awaited = bench.expect("TW+3 counts 9 modules",
        lambda: ...)``, then the write, then ``assert awaited.within(limit, every=poll)``.  ``condition`` is read
        now: if it already holds, the wait could be satisfied by the PLC's previous state, and
        :class:`hil.core.evidence.StaleEvidence` (reported as a test error naming ``what``) is raised instead."""
        ...

    def exclusive(self) -> AbstractContextManager[None]:
        """``with bench.exclusive():`` — the wire is this test's across several requests: in a run with lanes
        (``hil run --lanes``) no other lane's request comes between them, for a step whose timing matters (a set
        and an edge within one second of the PLC's clock).  Elsewhere it changes nothing."""
        ...

    def cannot_reach(self, *names: str) -> str | None:
        """Why this bench cannot read and write ``names`` (elements or ranges, ``"R4128-R4134"``): unreachable over
        the wire, or not in ``[safety] writable``.  None when it can; a test skips with the reason."""
        ...

    def unreachable_reason(self, name: str) -> str | None:
        """Why the wire cannot reach ``name`` (None when it can)."""
        ...

    def identity(self) -> dict[str, str]:
        """What the family adds to the PLC's identity in reports (e.g. the RTC chip)."""
        ...

    def end_test(self) -> None:
        """Put the PLC back now, as the fixture does when the test ends (idempotent; for a test's own steps)."""
        ...


class BenchWithFaults(BenchView, Protocol):
    @property
    def faults(self) -> Faults:
        """The profile's fault injectors (``[faults.<name>]``)."""
        ...


def members(face: type) -> dict[str, bool]:
    """The names a Protocol declares, over its Protocol bases: name → True for a method, False for a value (an
    attribute or a property).  What :mod:`hil.bench.view` builds a proxy of."""
    out: dict[str, bool] = {}
    for klass in reversed(face.__mro__):
        if klass is object or klass is Protocol or not getattr(klass, "_is_protocol", False):
            continue
        for name in getattr(klass, "__annotations__", {}):
            if not name.startswith("_"):
                out[name] = False
        for name, value in vars(klass).items():
            if name.startswith("_"):
                continue
            out[name] = callable(value) and not isinstance(value, (property, staticmethod, classmethod))
    return out


__all__ = ["BenchTime", "BenchView", "BenchWithFaults", "FaultInjector", "Faults", "PlcIO", "members"]
