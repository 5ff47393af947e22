"""The S7-200 SMART's clock model (manual: READ_RTC / SET_RTC / SET_RTC_I; spec/s7-200smart-rtc.md): the CPU's
time-of-day clock and its instructions (:class:`S7Clock`), and the bench's clock test program that runs them on
rising edges of its trigger bits (:class:`RtcTestProgram`).  The memory is memory.py's, the engine cpu.py's.
"""

from __future__ import annotations

import datetime as dt
import math
from typing import TYPE_CHECKING

from hil.families.s7smart.address import S7Address, parse_s7
from hil.families.s7smart.layout import S7RtcLayout
from hil.families.s7smart.protocol import timebuf
from hil.sim.model import Model

if TYPE_CHECKING:
    from hil.families.s7smart.sim.cpu import S7Emulator
    from hil.families.s7smart.sim.memory import S7Memory

SM4_3 = parse_s7("SM4.3")  # set when READ_RTC/SET_RTC collide (main program vs interrupt)


class S7Clock(Model["S7Emulator"]):
    """The CPU's time-of-day clock and the clock instructions.  Time is an anchor plus virtual seconds."""

    name = "s7-clock"

    def __init__(self, *, has_rtc: bool = True, start: dt.datetime | None = None) -> None:
        self.has_rtc = has_rtc
        self.start = timebuf.POWER_LOSS_TIME if (start is None or not has_rtc) else start.replace(microsecond=0)
        self._anchor = self.start
        self._anchor_now = 0.0

    def power_on(self, emu: S7Emulator) -> None:
        self._anchor, self._anchor_now = self.start, emu.now

    def power_cycle(self, emu: S7Emulator, *, backup_expired: bool) -> None:
        if backup_expired or not self.has_rtc:  # CR40/CR60: no clock to keep; others after the back-up ran out
            self._anchor, self._anchor_now = timebuf.POWER_LOSS_TIME, emu.now

    def time(self, now: float) -> dt.datetime:
        """The clock's time at ``now``.  It keeps only the year's last two digits (the manual): one second after
        2099-12-31 23:59:59 it shows 2000-01-01 00:00:00, and a century of its seconds is the 25 leap years of
        2000–2099 (no 2100, which READ_RTC could not encode)."""
        since = (self._anchor - timebuf.POWER_LOSS_TIME).total_seconds() + math.floor(now - self._anchor_now + 1e-9)
        return timebuf.POWER_LOSS_TIME + dt.timedelta(seconds=since % timebuf.CENTURY_SECONDS)

    def load(self, now: float, when: dt.datetime) -> None:
        self._anchor, self._anchor_now = when, now

    # -- the instructions: each returns the error code (0 = ENO 1) -----------------------------------------
    def read_rtc(self, now: float) -> tuple[bytes, int]:
        return self.encode(self.time(now)), timebuf.ERROR_NONE

    def set_rtc(self, now: float, buffer: bytes) -> int:
        try:
            when = self.decode(buffer)
        except timebuf.TimeBufferError as exc:
            return exc.code
        self.load(now, when)
        return timebuf.ERROR_NONE

    def set_rtc_i(self, now: float, buffer: bytes) -> int:
        try:
            bcd = timebuf.int_to_bcd(buffer)
        except timebuf.TimeBufferError as exc:
            return exc.code
        return self.set_rtc(now, bcd)

    # Hooks the codec provides; broken emulators override them.
    def decode(self, buffer: bytes) -> dt.datetime:
        return timebuf.decode(buffer)

    def encode(self, when: dt.datetime) -> bytes:
        return timebuf.encode(when)


class RtcTestProgram(Model["S7Emulator"]):
    """The bench's clock test program: on a rising edge of a trigger bit run the instruction on its buffer, then
    put ENO and the error code (GET_ERROR) where the layout says, and copy SM4.3."""

    name = "s7-rtc-program"

    def __init__(self, layout: S7RtcLayout) -> None:
        self.layout = layout
        self._previous: dict[S7Address, int] = {}

    def power_on(self, emu: S7Emulator) -> None:
        self._previous = dict.fromkeys(self.layout.triggers(), 0)

    def power_cycle(self, emu: S7Emulator, *, backup_expired: bool) -> None:
        self.power_on(emu)

    def fires(self, previous: int, now: int) -> bool:
        """EU: a rising edge.  (A level-triggered program would fire on ``now`` alone.)"""
        return bool(now and not previous)

    def scan(self, emu: S7Emulator) -> None:
        mem: S7Memory = emu.memory
        clock = emu.model(S7Clock)
        if clock is None:
            return
        lay = self.layout
        for trigger in lay.triggers():
            level = mem.get(trigger)
            fire = self.fires(self._previous.get(trigger, 0), level)
            self._previous[trigger] = level
            if not fire:
                continue
            if trigger == lay.read_trigger:
                data, error = clock.read_rtc(emu.now)
                if error == timebuf.ERROR_NONE:
                    mem.write_bytes("V", lay.read_buffer.byte, data)
            elif trigger == lay.set_trigger:
                error = clock.set_rtc(emu.now, mem.read_bytes("V", lay.set_buffer.byte, 8))
            elif lay.set_i_buffer is not None:  # (SET_RTC_I's trigger: the profile names its buffer with it)
                error = clock.set_rtc_i(emu.now, mem.read_bytes("V", lay.set_i_buffer.byte, 8))
            else:
                continue
            mem.set(lay.eno, 1 if error == timebuf.ERROR_NONE else 0)
            mem.set(lay.error, error)
            if lay.sm4_3 is not None:
                mem.set(lay.sm4_3, mem.get(SM4_3))

    def next_event(self, now: float) -> float:
        return math.inf  # acts only on trigger changes, which arrive with requests
