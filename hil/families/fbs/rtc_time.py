"""RtcTime: the seven RTC registers R4128–R4134 as one value, with the FBs rules for a valid time.

The FBs clock keeps a two-digit year (0–99 = 2000–2099, leap year when ``year % 4 == 0``, which is exact in
that century) and a weekday register that the PLC range-checks but does not tie to the date.  ``RtcTime`` holds
raw register values on purpose, including invalid ones, so a suite can send "31 April" and watch M1955.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from dataclasses import dataclass

from hil.core.errors import InvalidValue

#: Calendar time of two-digit year 0 (2000-01-01 00:00:00).
YEAR_BASE = 2000
EPOCH = dt.datetime(YEAR_BASE, 1, 1)
#: Seconds in the chip's 100-year span 2000–2099 (25 leap years); the chip's year wraps 2099 → 2000 after it.
CENTURY_SECONDS = 36525 * 86400

#: D4053 codes (manual ch. 15).
CHIP_NAMES: dict[int, str] = {0: "none", 1: "HT1381", 2: "ISL1208", 3: "S-35390A"}

FIELDS = ("second", "minute", "hour", "day", "month", "year", "weekday")

_DAYS = (31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31)


def is_leap(year: int) -> bool:
    """Two-digit FBs year (0–99): every fourth year is leap; 2000 is, and 2100 is outside the range."""
    return year % 4 == 0


def days_in_month(year: int, month: int) -> int:
    """Days in ``month`` (1–12) of two-digit ``year``; 31 for an invalid month so only the month is blamed."""
    if not 1 <= month <= 12:
        return 31
    return 29 if month == 2 and is_leap(year) else _DAYS[month - 1]


def weekday_of(year: int, month: int, day: int) -> int:
    """0 = Sunday … 6 = Saturday ([our choice] numbering, fbs-rtc.md) for a valid two-digit-year date."""
    return (dt.date(YEAR_BASE + year, month, day).weekday() + 1) % 7  # Python: Monday = 0


@dataclass(frozen=True)
class RtcTime:
    """Register values of R4128–R4134, in that order.  Not validated on construction (see :meth:`validate`)."""

    second: int
    minute: int
    hour: int
    day: int
    month: int
    year: int  # 0–99 = 2000–2099
    weekday: int  # 0 = Sunday

    # -- conversions ----------------------------------------------------------------------------------------
    @classmethod
    def from_datetime(cls, when: dt.datetime) -> RtcTime:
        """The RTC registers for ``when`` (sub-seconds dropped, weekday from the date); year must be 2000–2099."""
        if not YEAR_BASE <= when.year <= YEAR_BASE + 99:
            raise InvalidValue(f"the FBs RTC holds years 2000–2099 only, not {when.year} ({when.isoformat()})")
        return cls(when.second, when.minute, when.hour, when.day, when.month, when.year - YEAR_BASE,
                   weekday_of(when.year - YEAR_BASE, when.month, when.day))

    def to_datetime(self) -> dt.datetime:
        """The calendar time (naive); raises ValueError naming every invalid field.  The weekday is not used."""
        self.check()
        return dt.datetime(YEAR_BASE + self.year, self.month, self.day, self.hour, self.minute, self.second)

    @classmethod
    def from_registers(cls, values: Sequence[int]) -> RtcTime:
        """From the 7 values of R4128–R4134 (as read; unvalidated)."""
        if len(values) != 7:
            raise InvalidValue(f"R4128–R4134 are 7 registers, got {len(values)} values: {list(values)}")
        return cls(*(int(v) for v in values))

    def to_registers(self) -> list[int]:
        """The 7 values for R4128–R4134."""
        return [self.second, self.minute, self.hour, self.day, self.month, self.year, self.weekday]

    def hour_minute_word(self) -> int:
        """R4135: hour in the high byte, minute in the low byte, binary (13:45 → 0x0D2D)."""
        return (self.hour & 0xFF) << 8 | (self.minute & 0xFF)

    def with_weekday_from_date(self) -> RtcTime:
        """The same time with the weekday the date implies (the date must be valid)."""
        return RtcTime(self.second, self.minute, self.hour, self.day, self.month, self.year,
                       weekday_of(self.year, self.month, self.day))

    # -- validity ---------------------------------------------------------------------------------------------
    def validate(self) -> list[str]:
        """Names of every invalid field (empty = valid), in register order.

        A day that does not exist in its month/year is the day's fault (31 April, 29 Feb 2023); the weekday is
        range-checked only, as the PLC does ([our choice], fbs-rtc.md).
        """
        bad = []
        if not 0 <= self.second <= 59:
            bad.append("second")
        if not 0 <= self.minute <= 59:
            bad.append("minute")
        if not 0 <= self.hour <= 23:
            bad.append("hour")
        if not 1 <= self.day <= days_in_month(self.year, self.month):
            bad.append("day")
        if not 1 <= self.month <= 12:
            bad.append("month")
        if not 0 <= self.year <= 99:
            bad.append("year")
        if not 0 <= self.weekday <= 6:
            bad.append("weekday")
        return bad

    @property
    def is_valid(self) -> bool:
        return not self.validate()

    def check(self) -> None:
        """Raise ValueError listing every invalid field with its value."""
        bad = self.validate()
        if bad:
            detail = ", ".join(f"{name}={getattr(self, name)}" for name in bad)
            raise InvalidValue(f"invalid RTC time {self}: {detail}")

    def __str__(self) -> str:
        return (f"{YEAR_BASE + self.year:04d}-{self.month:02d}-{self.day:02d} "
                f"{self.hour:02d}:{self.minute:02d}:{self.second:02d} (weekday {self.weekday})")


__all__ = ["RtcTime", "is_leap", "days_in_month", "weekday_of", "CHIP_NAMES", "FIELDS", "EPOCH",
           "CENTURY_SECONDS", "YEAR_BASE"]
