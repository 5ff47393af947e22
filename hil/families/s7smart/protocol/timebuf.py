"""The 8-byte READ_RTC/SET_RTC time buffer T, both ways, and SET_RTC_I's integer variant.

T = year, month, day, hour, minute, second, reserved (00), day of week — every byte BCD; year 00–99 is
2000–2099; weekday 1 = Sunday … 7 = Saturday, ignored by SET_RTC and computed from the date by READ_RTC.
Any byte that is not legal — a non-BCD nibble, a value out of range, a day that does not exist in its month
(leap years right through 2099), a non-zero reserved byte — makes SET_RTC refuse with non-fatal error 0007H.
"""

from __future__ import annotations

import calendar
import datetime as dt
from collections.abc import Sequence

from hil.core.errors import InvalidValue

ERROR_NONE = 0x0000
ERROR_INDIRECT = 0x0006  # indirect address error
ERROR_T_DATA = 0x0007  # "T data error": an invalid time buffer (or a colliding access, with SM4.3)

#: Where the clock starts after the back-up time ran out (and always at power-on on a CR40/CR60).
POWER_LOSS_TIME = dt.datetime(2000, 1, 1, 0, 0, 0)  # a Saturday: weekday 7
#: Seconds from 2000-01-01 to 2100-01-01: the clock's two-digit years come round again after them.
CENTURY_SECONDS = int((dt.datetime(2100, 1, 1) - POWER_LOSS_TIME).total_seconds())

FIELDS = ("year", "month", "day", "hour", "minute", "second", "reserved", "weekday")
_RANGES = {"year": (0, 99), "month": (1, 12), "day": (1, 31), "hour": (0, 23), "minute": (0, 59),
           "second": (0, 59), "reserved": (0, 0), "weekday": (1, 7)}


class TimeBufferError(ValueError):
    """A time buffer SET_RTC would refuse; ``code`` is the PLC's error code (0007H) and ``problems`` the fields."""

    def __init__(self, problems: list[str], code: int = ERROR_T_DATA) -> None:
        self.problems = problems
        self.code = code
        super().__init__(f"time buffer error {code:04X}H: {', '.join(problems)}")


def to_bcd(value: int) -> int:
    if not 0 <= value <= 99:
        raise InvalidValue(f"{value} does not fit one BCD byte (00–99)")
    return value // 10 << 4 | value % 10


def from_bcd(byte: int) -> int | None:
    """The value of a BCD byte, or None when a nibble is not 0–9 (16#1A)."""
    hi, lo = byte >> 4 & 0xF, byte & 0xF
    return hi * 10 + lo if hi <= 9 and lo <= 9 and 0 <= byte <= 0xFF else None


def weekday(date: dt.date) -> int:
    """S7 day of week: 1 = Sunday … 7 = Saturday."""
    return date.isoweekday() % 7 + 1


def problems(values: Sequence[int | None], *, check_weekday: bool = False) -> list[str]:
    """Fields of a decoded buffer (None = not BCD) that SET_RTC would refuse.  The weekday is ignored on set."""
    if len(values) != 8:
        return [f"length {len(values)} (must be 8 bytes)"]
    out: list[str] = []
    good: dict[str, int] = {}
    for name, value in zip(FIELDS, values):
        if name == "weekday" and not check_weekday:
            continue
        lo, hi = _RANGES[name]
        if value is None:
            out.append(f"{name} not BCD")
        elif not lo <= value <= hi:
            out.append(f"{name} {value} outside {lo:02d}–{hi:02d}")
        else:
            good[name] = value
    if {"year", "month", "day"} <= good.keys():
        year, month, day = 2000 + good["year"], good["month"], good["day"]
        if day > calendar.monthrange(year, month)[1]:
            out.append(f"day {day} does not exist in {year}-{month:02d}")
    return out


def decode(buffer: bytes | Sequence[int], *, check_weekday: bool = False) -> dt.datetime:
    """The time in a BCD buffer as SET_RTC would take it; TimeBufferError (0007H) when it would refuse."""
    data = bytes(buffer)
    values = [from_bcd(b) for b in data]
    found = problems(values, check_weekday=check_weekday)
    if found:
        raise TimeBufferError(found)
    # (every field BCD: problems() found none that is not)
    year, month, day, hour, minute, second = (v for v in values[:6] if v is not None)
    return dt.datetime(2000 + year, month, day, hour, minute, second)


def encode(when: dt.datetime) -> bytes:
    """The BCD buffer READ_RTC leaves for ``when``, weekday computed from the date."""
    _check_year(when)
    return bytes(to_bcd(v) for v in (when.year - 2000, when.month, when.day, when.hour, when.minute,
                                     when.second, 0, weekday(when.date())))


# -- SET_RTC_I: the same eight bytes as plain integers ---------------------------------------------------------
def encode_int(when: dt.datetime) -> bytes:
    """SET_RTC_I's buffer for ``when``: decimal integers, not BCD (weekday computed, though ignored)."""
    _check_year(when)
    return bytes((when.year - 2000, when.month, when.day, when.hour, when.minute, when.second, 0,
                  weekday(when.date())))


def int_to_bcd(buffer: bytes | Sequence[int]) -> bytes:
    """What SET_RTC_I hands SET_RTC: each integer byte converted to BCD; TimeBufferError when it cannot be
    (a byte above 99), so the instruction refuses with 0007H as SET_RTC would."""
    data = bytes(buffer)
    if len(data) != 8:
        raise TimeBufferError([f"length {len(data)} (must be 8 bytes)"])
    bad = [f"{name} {b} not 0–99" for name, b in zip(FIELDS, data) if b > 99 and name != "weekday"]
    if bad:
        raise TimeBufferError(bad)
    return bytes(to_bcd(b if b <= 99 else 0) for b in data)


def _check_year(when: dt.datetime) -> None:
    if not 2000 <= when.year <= 2099:
        raise InvalidValue(f"{when:%Y-%m-%d}: the S7-200 SMART clock holds 2000–2099 only")


def hex_bytes(buffer: bytes | Sequence[int]) -> str:
    """``24 02 29 12 00 00 00 05`` — how a buffer reads in a status chart."""
    return " ".join(f"{b:02X}" for b in bytes(buffer))
