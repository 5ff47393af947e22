"""S7Plc: the facade S7 suites use through the bench fixture (``bench.plc``) — the clock test program's
procedures, not byte math.

``plc.rtc.set(buffer)`` writes the 8-byte buffer where the bench's test program expects it, gives SET_RTC its
rising edge, and reads back ENO and the error code; ``plc.rtc.read()`` does the same for READ_RTC and returns the
buffer.  Outcomes are reported, never judged: suites decide what is right.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import cast

from hil.bench.guard import Clock
from hil.core.errors import HilError, InvalidValue
from hil.core.timebase import Timebase, nearest_whole_second, next_whole_second, wait_until
from hil.families.s7smart.address import S7Address, units
from hil.families.s7smart.layout import S7RtcLayout
from hil.families.s7smart.protocol import timebuf
from hil.families.s7smart.transport.io import ClockedS7Io, S7Io
from hil.io.status import PlcStatus


def clock_functions(io: S7Io) -> ClockedS7Io | None:
    """The wire's clock functions (the S7 protocol's: ``has_cpu_clock``), or None on a wire without them."""
    return cast(ClockedS7Io, io) if getattr(io, "has_cpu_clock", False) else None


@dataclass(frozen=True)
class ClockResult:
    """What the test program left after a clock instruction."""

    eno: int  # 1 = the instruction completed
    error: int  # GET_ERROR after it: 0000H, 0007H (T data error) …
    buffer: bytes = b""  # READ_RTC's buffer (empty for SET_RTC)
    sm4_3: int | None = None  # SM4.3 copy, when the layout has one

    @property
    def accepted(self) -> bool:
        return self.eno == 1 and self.error == 0

    def __str__(self) -> str:
        text = f"ENO={self.eno} error={self.error:04X}H"
        return text + (f" T=[{timebuf.hex_bytes(self.buffer)}]" if self.buffer else "")


class S7Rtc:
    def __init__(self, plc: S7Plc, layout: S7RtcLayout) -> None:
        self.plc = plc
        self.layout = layout

    @property
    def has_set_i(self) -> bool:
        return self.layout.set_i_trigger is not None

    def set(self, buffer: bytes | list[int], *, hold: bool = False) -> ClockResult:
        """SET_RTC on ``buffer`` (8 BCD bytes, as given: nothing is checked here).  ``hold=True`` leaves the
        trigger at 1 afterwards (for edge tests); :meth:`release` drops it."""
        self.plc.io.write_v(self.layout.set_buffer.byte, _eight(buffer))
        return self._pulse(self.layout.set_trigger, hold)

    def set_int(self, buffer: bytes | list[int], *, hold: bool = False) -> ClockResult:
        """SET_RTC_I (library instruction) on ``buffer`` (8 plain integers)."""
        if self.layout.set_i_trigger is None or self.layout.set_i_buffer is None:
            raise InvalidValue("the bench's [s7rtc] has no set_i_trigger/set_i_buffer")
        self.plc.io.write_v(self.layout.set_i_buffer.byte, _eight(buffer))
        return self._pulse(self.layout.set_i_trigger, hold)

    def write_set_buffer(self, buffer: bytes | list[int]) -> None:
        """Change the SET_RTC buffer without touching the trigger."""
        self.plc.io.write_v(self.layout.set_buffer.byte, _eight(buffer))

    def read(self) -> ClockResult:
        """READ_RTC: the buffer as the program left it, with ENO and the error code."""
        result = self._pulse(self.layout.read_trigger, False)
        data = self.plc.io.read_v(self.layout.read_buffer.byte, 8)
        return ClockResult(result.eno, result.error, data, result.sm4_3)

    def release(self) -> None:
        for trigger in self.layout.triggers():
            if self.plc.io.read(trigger):
                self.plc.io.write(trigger, 0)
        self.plc.settle()

    def read_time(self) -> dt.datetime:
        """The clock as a datetime (READ_RTC, decoded); TimeBufferError if the buffer is not a valid time."""
        return timebuf.decode(self.read().buffer)

    # -- the CPU's own clock functions (over the S7 protocol; None where the wire has none) ----------------------
    def cpu_clock(self) -> dt.datetime | None:
        """The time-of-day clock read with the protocol's clock function, or None on a wire without one."""
        clocked = clock_functions(self.plc.io)
        return clocked.cpu_clock() if clocked is not None else None

    def set_cpu_clock(self, when: dt.datetime) -> None:
        """Set the clock with the protocol's clock function (HilError on a wire without one)."""
        clocked = clock_functions(self.plc.io)
        if clocked is None:
            raise HilError(f"{self.plc.io.description} has no clock functions (use s7+tcp://)")
        clocked.set_cpu_clock(when)

    def sync_to_host(self) -> ClockResult:
        """Set the clock to the bench's calendar time, at its next whole second."""
        return self.sync_to(self.plc.time.calendar)

    def sync_to(self, clock: Callable[[], dt.datetime]) -> ClockResult:
        """SET_RTC to what ``clock()`` says, at its next whole second (the bench restores a clock a test set with
        this exactly: ``clock`` is then the CPU's original time carried forward)."""
        self.release()
        target = next_whole_second(clock())
        self.write_set_buffer(timebuf.encode(target))
        wait_until(self.plc.time, clock, target)
        return self._pulse(self.layout.set_trigger, False)

    def set_now(self, clock: Callable[[], dt.datetime]) -> ClockResult:
        """SET_RTC at once to what ``clock()`` says, to the nearest second (how the bench puts the clock back
        between two tests, without waiting for a whole second)."""
        self.release()
        return self.set(timebuf.encode(nearest_whole_second(clock())))

    def side_effects(self, written: Iterable[S7Address]) -> list[S7Address]:
        """What the test program writes because of these writes: a trigger's edge makes it leave ENO and the
        error code (and SM4.3's copy) — READ_RTC its buffer too.  The guard journals them as originals."""
        lay = self.layout
        fired = set(lay.triggers()).intersection(written)
        if not fired:
            return []
        out = [lay.eno, *units(lay.error), *([lay.sm4_3] if lay.sm4_3 is not None else [])]
        if lay.read_trigger in fired:
            out += units(S7Address("V", lay.read_buffer.byte, None, 8))
        return out

    def _pulse(self, trigger: S7Address, hold: bool) -> ClockResult:
        io = self.plc.io
        if io.read(trigger):  # already high: an edge needs a low first
            io.write(trigger, 0)
            self.plc.settle()
        io.write(trigger, 1)
        self.plc.settle()
        if not hold:
            io.write(trigger, 0)
            self.plc.settle()
        return self.result()

    def result(self) -> ClockResult:
        io, lay = self.plc.io, self.layout
        return ClockResult(io.read(lay.eno), io.read(lay.error),
                           sm4_3=io.read(lay.sm4_3) if lay.sm4_3 is not None else None)


class S7Plc:
    """One S7-200 SMART reached through ``io`` (normally the bench's guarded io)."""

    family = "s7-200smart"

    def __init__(self, io: S7Io, timebase: Timebase, *, layout: S7RtcLayout | None = None,
                 settle_scans: int = 2) -> None:
        self.io = io
        self.time = timebase
        self.settle_scans = settle_scans
        self.rtc: S7Rtc | None = S7Rtc(self, layout) if layout is not None else None

    def status(self) -> PlcStatus:
        return self.io.status()

    def clock(self) -> Clock | None:
        """The CPU clock as the bench's guard keeps it: before the first write of a SET_RTC/SET_RTC_I trigger (or
        a clock-function set) its time is journaled, and it is put back at its original offset from the bench's
        time — with the wire's clock functions where it has them (s7+tcp://), else with the test program's
        READ_RTC/SET_RTC.  None when this bench has neither."""
        io, rtc = self.io, self.rtc
        touches = frozenset(a for t in (rtc.layout.set_trigger, rtc.layout.set_i_trigger) if t is not None
                            for a in units(t)) if rtc is not None else frozenset()
        clocked = clock_functions(io)
        if clocked is not None:
            def put(when: Callable[[], dt.datetime], exact: bool) -> None:
                if not exact:
                    clocked.set_cpu_clock(nearest_whole_second(when()))
                    return
                target = next_whole_second(when())
                wait_until(self.time, when, target)
                clocked.set_cpu_clock(target)
            return Clock(touches, clocked.cpu_clock, put, self.time)
        if rtc is None:
            return None

        def put_by_program(when: Callable[[], dt.datetime], exact: bool) -> None:
            result = rtc.sync_to(when) if exact else rtc.set_now(when)
            if not result.accepted:
                raise HilError(f"SET_RTC refused the restored time ({result})")
        return Clock(touches, rtc.read_time, put_by_program, self.time)

    def settle(self, scans: int | None = None) -> None:
        """Let the program complete whole scans since our last write: each round trip spans at least one scan
        (MBUS_SLAVE answers from the program's scan), so a few cheap reads do it on a CPU and the emulator."""
        for _ in range(self.settle_scans if scans is None else scans):
            self.io.status()


def _eight(buffer: bytes | list[int]) -> bytes:
    data = bytes(buffer)
    if len(data) != 8:
        raise InvalidValue(f"a clock buffer has 8 bytes, not {len(data)}")
    return data
