"""The RTC model's side of the emulator's speed-ups, and what only deliberately broken variants need — no PLC
has these: the read-out skipped while the chip still shows the second already copied out (it runs at every
request), the footprint a batch of other models' scans relies on (models/span.py), and an invalid time's
seconds (only a broken ``validate`` lets one reach the chip).  The manual's clock is models/rtc.py; tests/
test_rtc_model.py and test_model_golden*.py hold these to it.  :class:`RtcShortcuts` is mixed into :class:`RtcModel`.
"""

from __future__ import annotations

import datetime as dt
import math
from typing import TYPE_CHECKING, ClassVar

from hil.families.fbs import registers as reg
from hil.families.fbs.address import parse
from hil.families.fbs.rtc_time import CENTURY_SECONDS, EPOCH, RtcTime

if TYPE_CHECKING:
    from hil.families.fbs.sim.plc import Emulator

#: R4128–R4135, the read-out's words
_CLOCK = slice(parse(reg.RTC_SECOND).index, parse(reg.RTC_HOUR_MINUTE).index + 1)
#: every element the clock reads or writes at a scan (its footprint)
_TOUCHED = frozenset([("R", i) for i in range(_CLOCK.start, _CLOCK.stop)] + [
    (a.kind, a.index) for a in map(parse, (reg.RTC_HOLD, reg.RTC_ADJUST_30S, reg.RTC_INSTALLED, reg.RTC_SET_ERROR,
                                           reg.RTC_CHIP, reg.RTC_RATE_CODE))])

def rolled_over_seconds(t: RtcTime) -> int:
    """An invalid time's seconds since 2000-01-01, taken arithmetically (31 April = 1 May, second 60 = the next
    minute), as a counter chip would roll it over, instead of crashing the emulator."""
    month = min(max(t.month, 1), 12)
    first = dt.date(2000 + t.year % 100, month, 1)
    days = (first - EPOCH.date()).days + t.day - 1
    return (days * 86400 + t.hour * 3600 + t.minute * 60 + t.second) % CENTURY_SECONDS


class RtcShortcuts:
    """The read-out cache and the footprint of an RTC model."""

    #: the model class whose steps the shortcuts assume (set by models/rtc.py)
    plain: ClassVar[type]

    def init_read_out(self) -> None:
        self._shown_second: int | None = None  # the chip second last copied out, and R4128–R4135 as written
        self._shown: list[int] = []

    def _read_out(self, emu: "Emulator") -> None:
        """copy_out(read_chip(now)), skipped when the chip still shows the second already in R4128–R4135 (the
        unmodified model only: a variant overriding a step always takes the full path)."""
        if not self._plain:
            self.copy_out(emu, self.read_chip(emu.now))
            return
        # chip_seconds(emu.now), inlined
        second = math.floor((self._anchor_s + (emu.now - self._anchor_t) * self._rate) % CENTURY_SECONDS)
        words = emu.memory.words["R"]
        if second == self._shown_second and words[_CLOCK] == self._shown:
            return
        self.copy_out(emu, self.read_chip(emu.now))
        self._shown_second, self._shown = second, words[_CLOCK]

    def next_event(self, now: float) -> float:
        """Never: the chip's time is a formula of virtual time, and the engine always runs the scan after a
        request before it jumps, so edges and new D4054 codes are seen on time."""
        return math.inf

    def footprint(self) -> frozenset[tuple[str, int]]:
        """R4128–R4135, M1952–M1955, D4053, D4054: a scan that skips the clock loses nothing but its read-out,
        which the next scan writes whole (skipping it is safe when nothing else touches these).  None for a
        variant with a scan of its own (a deliberately broken clock): what it touches is not known here."""
        if type(self).scan is not self.plain.scan:
            return None
        return _TOUCHED
