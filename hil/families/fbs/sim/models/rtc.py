"""RtcModel: the FBs real-time clock (manual ch. 15, restated in shared/spec/fbs-rtc.md).

The chip keeps time *analytically* from the emulator's virtual clock: its reading is
``anchor + (now − anchor_t) × rate`` where ``rate = 1 + ppm·1e−6 − correction/86400``.  There is no
per-second event, so ``emu.advance(86400)`` is one jump and a simulated day of drift costs nothing.  Anything
that changes the chip (a set, a ±30 s correction, a new D4054 code) re-anchors it at the scan that sees it.

Each behaviour the spec describes is one small method with a docstring, so a test can build a deliberately
broken PLC by subclassing and overriding exactly one of them (e.g. a ``validate`` that forgets 31 April).
"""

from __future__ import annotations

import datetime as dt
import math
from typing import TYPE_CHECKING

from hil.core.errors import InvalidValue
from hil.families.fbs import registers as reg
from hil.families.fbs.address import parse
from hil.families.fbs.d4054 import rate_for_code
from hil.families.fbs.rtc_time import CENTURY_SECONDS, CHIP_NAMES, EPOCH, RtcTime
from hil.sim.model import Model

if TYPE_CHECKING:
    from hil.families.fbs.sim.plc import Emulator

# Direct bank indexes: models touch memory banks directly for speed (memory.py).
_FIRST = parse(reg.RTC_SECOND).index  # R4128
_HOUR_MINUTE = parse(reg.RTC_HOUR_MINUTE).index  # R4135
_HOLD = parse(reg.RTC_HOLD).index  # M1952
_ADJUST = parse(reg.RTC_ADJUST_30S).index  # M1953
_INSTALLED = parse(reg.RTC_INSTALLED).index  # M1954
_SET_ERROR = parse(reg.RTC_SET_ERROR).index  # M1955
_CHIP = parse(reg.RTC_CHIP).index  # D4053
_RATE_CODE = parse(reg.RTC_RATE_CODE).index  # D4054

S35390A = 3
#: days in the chip's century 2000–2099: its day count wraps with its year
CENTURY_DAYS = CENTURY_SECONDS // 86400


def seconds_of(t: RtcTime) -> int:
    """Seconds since 2000-01-01 00:00:00 for ``t`` (the weekday is ignored).

    Exact for a valid time.  An invalid one only reaches the chip through a deliberately broken ``validate``;
    it is then taken arithmetically (31 April = 1 May, second 60 = the next minute), as a counter chip would
    roll it over, instead of crashing the emulator.
    """
    if t.is_valid:
        return int((t.to_datetime() - EPOCH).total_seconds())
    month = min(max(t.month, 1), 12)
    first = dt.date(2000 + t.year % 100, month, 1)
    days = (first - EPOCH.date()).days + t.day - 1
    return (days * 86400 + t.hour * 3600 + t.minute * 60 + t.second) % CENTURY_SECONDS


class RtcModel(Model["Emulator"]):
    """An RTC chip behind R4128–R4135, M1952–M1955, D4053, D4054.

    ``chip``: 0 none, 1 HT1381, 2 ISL1208, 3 S-35390A.  ``crystal_ppm``: positive = the chip runs fast.
    ``start``: what the chip shows at virtual t = 0.
    """

    name = "rtc"

    def __init__(self, chip: int = S35390A, crystal_ppm: float = 0.0,
                 start: dt.datetime | RtcTime | None = None) -> None:
        if chip not in CHIP_NAMES:
            raise InvalidValue(f"RTC chip must be one of {CHIP_NAMES} (D4053 codes), not {chip!r}")
        self.chip = chip
        self.crystal_ppm = float(crystal_ppm)
        if start is None:
            start = dt.datetime(2024, 1, 1)
        start_time = start if isinstance(start, RtcTime) else RtcTime.from_datetime(start)
        # The chip: its reading (seconds since 2000-01-01, fractional = sub-second phase) at virtual time
        # _anchor_t, and how many chip seconds pass per virtual second from then on.
        self._anchor_t = 0.0
        self._anchor_s = float(seconds_of(start_time))
        self._anchor_weekday = start_time.weekday  # what the chip's weekday counter shows at _anchor_s
        self._code = 0  # the D4054 value in force
        self._rate = self.chip_rate(self._code)
        self._hold = 0  # M1952 / M1953 as of the last scan, for edge detection
        self._adjust = 0

    # -- the engine's hooks ---------------------------------------------------------------------------------
    def power_on(self, emu: Emulator) -> None:
        mem = emu.memory
        self._hold = mem.bits["M"][_HOLD]
        self._adjust = mem.bits["M"][_ADJUST]
        self.on_rate_code(emu, mem.words["D"][_RATE_CODE])
        self.publish_chip(emu)
        if self.chip:
            self.copy_out(emu, self.read_chip(emu.now))

    def scan(self, emu: Emulator) -> None:
        mem = emu.memory
        m = mem.bits["M"]
        self.publish_chip(emu)
        hold, adjust = m[_HOLD], m[_ADJUST]
        if self.chip:
            code = mem.words["D"][_RATE_CODE]
            if code != self._code:
                self.on_rate_code(emu, code)
            if self._hold and not hold:
                self.on_hold_edge(emu)
            if adjust and not self._adjust:
                self.on_adjust_edge(emu)
            if not hold:
                self.copy_out(emu, self.read_chip(emu.now))
        self._hold, self._adjust = hold, adjust

    # -- the chip -------------------------------------------------------------------------------------------
    def chip_seconds(self, now: float) -> float:
        """The chip's reading at virtual time ``now``: seconds since 2000-01-01, wrapped at 2099 → 2000."""
        return (self._anchor_s + (now - self._anchor_t) * self._rate) % CENTURY_SECONDS

    def read_chip(self, now: float) -> RtcTime:
        """The time the chip shows at ``now`` (whole seconds; weekday from :meth:`weekday_after`)."""
        seconds = math.floor(self.chip_seconds(now))
        when = EPOCH + dt.timedelta(seconds=seconds)
        # chip days since the anchor, counted across the 2099 → 2000 wrap as one day like any other
        days = (seconds // 86400 - math.floor(self._anchor_s) // 86400) % CENTURY_DAYS
        return RtcTime(when.second, when.minute, when.hour, when.day, when.month, when.year - 2000,
                       self.weekday_after(days))

    def write_chip(self, emu: Emulator, t: RtcTime) -> None:
        """Load ``t`` into the chip at ``emu.now``.  Writing restarts the chip's second: the sub-second phase is
        zero at the write, so the next tick comes one (chip) second later — what a sync at a whole second wants.
        The weekday counter takes the weekday written, whatever the date's is (RTC-VAL-5)."""
        self._anchor_t = emu.now
        self._anchor_s = float(seconds_of(t))
        self._anchor_weekday = t.weekday % 7  # (% 7: only a broken ``validate`` lets 7 or more through)

    def chip_rate(self, code: int) -> float:
        """Chip seconds per virtual second with D4054 = ``code``."""
        return 1.0 + self.crystal_ppm * 1e-6 - self.correction_rate(code) / 86400.0

    def correction_rate(self, code: int) -> float:
        """s/day the chip is slowed by for D4054 = ``code``, in the manual's sign (the code for +r cancels a
        clock fast by r).  Only the S-35390A has one; 0000H and codes that are not 56xxH apply nothing
        ([our choice] — the manual is silent)."""
        if self.chip != S35390A:
            return 0.0
        try:
            return rate_for_code(code).s_per_day
        except ValueError:
            return 0.0

    def weekday_after(self, days: int) -> int:
        """The chip's weekday counter ``days`` chip days after the anchor (0 = Sunday): it advances by one
        (6 → 0) whenever the date advances and is never computed from the date, so after the wrap from Thursday
        31 Dec 2099 it shows Friday although 1 Jan 2000 was a Saturday (fbs-rtc.md, ±30 s correction)."""
        return (self._anchor_weekday + days) % 7

    # -- PLC behaviour ----------------------------------------------------------------------------------------
    def publish_chip(self, emu: Emulator) -> None:
        """D4053 = chip code (read-only for users, so rewritten every scan); M1954 = a chip is fitted."""
        emu.memory.words["D"][_CHIP] = self.chip
        emu.memory.bits["M"][_INSTALLED] = 1 if self.chip else 0

    def copy_out(self, emu: Emulator, t: RtcTime) -> None:
        """Read-out: R4128–R4134 := ``t`` and R4135 := hour<<8 | minute (every scan while M1952 = 0)."""
        words = emu.memory.words["R"]
        words[_FIRST:_FIRST + 7] = t.to_registers()
        words[_HOUR_MINUTE] = t.hour_minute_word()

    def validate(self, t: RtcTime) -> list[str]:
        """The fields the PLC finds invalid in a set request (empty = accept)."""
        return t.validate()

    def on_hold_edge(self, emu: Emulator) -> None:
        """Falling edge of M1952: set the chip from R4128–R4134 if valid (M1955 := 0), else leave the chip
        running on its previous time and M1955 := 1."""
        words = emu.memory.words["R"]
        requested = RtcTime.from_registers(words[_FIRST:_FIRST + 7])
        if self.validate(requested):
            emu.memory.bits["M"][_SET_ERROR] = 1
            return
        self.write_chip(emu, requested)
        emu.memory.bits["M"][_SET_ERROR] = 0

    def apply_30s(self, t: RtcTime) -> RtcTime:
        """±30 s correction of ``t``: seconds 0–29 → :00; 30–59 → :00 of the next minute, carrying through hour,
        day, month and year (2099 → 2000); the weekday counter advances by one when the date does."""
        when = t.to_datetime().replace(second=0)
        if t.second >= 30:
            when += dt.timedelta(minutes=1)
        if when.year > 2099:  # the chip's two-digit year wraps
            when = when.replace(year=2000)
        weekday = (t.weekday + (when.date() != t.to_datetime().date())) % 7
        return RtcTime(0, when.minute, when.hour, when.day, when.month, when.year - 2000, weekday)

    def on_adjust_edge(self, emu: Emulator) -> None:
        """Rising edge of M1953: apply :meth:`apply_30s` to the chip's current time."""
        self.write_chip(emu, self.apply_30s(self.read_chip(emu.now)))

    def on_rate_code(self, emu: Emulator, code: int) -> None:
        """A new D4054 value: re-anchor at ``emu.now`` (keeping the phase) and run at the new rate from here."""
        self._anchor_weekday = self.read_chip(emu.now).weekday
        self._anchor_s = self.chip_seconds(emu.now)
        self._anchor_t = emu.now
        self._code = code
        self._rate = self.chip_rate(code)

    def __repr__(self) -> str:
        return (f"<RtcModel {CHIP_NAMES[self.chip]} {self.crystal_ppm:+g} ppm "
                f"D4054={self._code:04X}H>")

