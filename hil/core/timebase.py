"""Time belongs to the bench: a reference clock and a way to let time pass, for a real PLC or the emulator.

* :class:`HostTimebase` — a real bench (or an external emulator): the host's clocks; ``wait`` sleeps, divided by
  the profile's ``time_scale`` for an accelerated external emulator.
* :class:`EmulatorTimebase` — the in-process emulator: ``wait`` advances virtual time; "host time" is a fixed
  calendar epoch plus virtual seconds, so a simulated day takes no wall day.
"""

from __future__ import annotations

import datetime as dt
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from hil.core.errors import InvalidValue


class Timebase(Protocol):
    def now(self) -> float:
        """Reference seconds (monotonic); differences measure elapsed bench time."""

    def calendar(self) -> dt.datetime:
        """The reference calendar time (naive, local) that an RTC should show when in sync."""

    def wait(self, seconds: float) -> None:
        """Let ``seconds`` of bench time pass."""

    @property
    def virtual(self) -> bool:
        """True when time is simulated (waiting costs no wall time)."""


class VirtualClock(Protocol):
    """What an emulator's engine offers a timebase: virtual seconds since power-on, and a way to let them pass."""

    now: float

    def advance(self, seconds: float) -> None: ...


WaitListener = Callable[[float, float], None]


class HostTimebase:
    virtual = False

    def __init__(self, time_scale: float = 1.0) -> None:
        if time_scale <= 0:
            raise InvalidValue(f"time_scale must be positive, not {time_scale}")
        self.time_scale = time_scale
        self.listeners: list[WaitListener] = []

    def now(self) -> float:
        return time.monotonic() * self.time_scale

    def calendar(self) -> dt.datetime:
        return dt.datetime.now()

    #: A listener's chunk: long waits are slept in pieces so listeners (a progress bar, a CI log line) see them.
    LISTENER_STEP = 0.25

    def add_wait_listener(self, listener: WaitListener) -> None:
        """Public callback: ``listener(seconds_done, seconds_total)`` is called at the start of every wait, after
        each piece of it and at its end (``done == total``), in bench seconds."""
        self.listeners.append(listener)

    def wait(self, seconds: float) -> None:
        if seconds <= 0:
            return
        listeners = self.listeners
        if not listeners:
            time.sleep(seconds / self.time_scale)
            return
        for listener in listeners:
            listener(0.0, seconds)
        done = 0.0
        while done < seconds:
            piece = min(self.LISTENER_STEP * self.time_scale, seconds - done)
            time.sleep(piece / self.time_scale)
            done = min(seconds, done + piece)
            for listener in listeners:
                listener(done, seconds)


@dataclass(frozen=True)
class HostClocks:
    """The host's clocks read together: the wall clock (UTC seconds since the epoch) and, where the OS has them,
    the time since boot (suspend included: a PLC's clock runs on while the host sleeps) and the boot's id.

    A bench keeps a clock's offset on its monotonic :meth:`Timebase.now` within a session; these are only for
    carrying an origin across sessions (a dead run's journal), where the boot clock tells a host clock that was
    stepped in between."""

    wall: float
    since_boot: float | None
    boot: str | None
    #: how far apart the wall clock and the boot clock were read (s): the pair is known together to ± half this
    spread: float = 0.0

    @classmethod
    def now(cls) -> HostClocks:
        # time.time() looked up at each call: the one place hil reads the host's wall clock for a clock's origin;
        # the boot clock read either side of it, so the pair's own uncertainty is measured, not assumed
        boottime = getattr(time, "CLOCK_BOOTTIME", None)
        before = time.clock_gettime(boottime) if boottime is not None else None
        wall = time.time()
        after = time.clock_gettime(boottime) if boottime is not None else None
        try:
            boot = Path("/proc/sys/kernel/random/boot_id").read_text().strip() or None
        except OSError:
            boot = None
        if before is None or after is None:
            return cls(wall, None, boot)
        return cls(wall, (before + after) / 2, boot, after - before)


def next_whole_second(when: dt.datetime) -> dt.datetime:
    """The first whole second at or after ``when``: where a clock is set, so that its seconds tick with the
    reference's (a clock keeps whole seconds and restarts its second when set)."""
    return when.replace(microsecond=0) + dt.timedelta(seconds=1 if when.microsecond else 0)


def nearest_whole_second(when: dt.datetime) -> dt.datetime:
    """``when`` rounded to the nearest whole second (a clock set at once, within half a second of ``when``)."""
    return (when + dt.timedelta(microseconds=500_000)).replace(microsecond=0)


def wait_until(timebase: Timebase, clock: Callable[[], dt.datetime], when: dt.datetime) -> None:
    """Let bench time pass until ``clock()`` says ``when`` (at once if it already does)."""
    remaining = (when - clock()).total_seconds()
    if remaining > 0:
        timebase.wait(remaining)


def timebase_for(emulator: VirtualClock | None, epoch: dt.datetime, time_scale: float = 1.0) -> Timebase:
    """The bench's time: virtual with an in-process emulator (``emulator``), else the host's (÷ ``time_scale``
    for an accelerated external emulator).  The one place that decides it."""
    return EmulatorTimebase(emulator, epoch) if emulator is not None else HostTimebase(time_scale)


class EmulatorTimebase:
    virtual = True

    def __init__(self, emulator: VirtualClock, epoch: dt.datetime | None = None) -> None:
        self.emulator = emulator
        # Calendar time at virtual t = 0; whole seconds so that "host time" has no sub-second offset.
        self.epoch = (epoch or dt.datetime.now()).replace(microsecond=0)

    def now(self) -> float:
        return self.emulator.now

    def calendar(self) -> dt.datetime:
        return self.epoch + dt.timedelta(seconds=self.emulator.now)

    def wait(self, seconds: float) -> None:
        self.emulator.advance(seconds)
