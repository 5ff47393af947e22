"""A clock's own day counter with wrong month lengths, for broken emulators of both families: what a chip whose
calendar table is wrong shows after running ``seconds`` from a time that was set (the set itself validated right)."""

from __future__ import annotations

import calendar
from collections.abc import Callable

#: (two-digit year, month) → days in that month, as a broken chip counts them
DaysIn = Callable[[int, int], int]


def true_days(year: int, month: int) -> int:
    return calendar.monthrange(2000 + year, month)[1]


def february_always_28(year: int, month: int) -> int:
    """No leap years: 29 February is never reached."""
    return 28 if month == 2 else true_days(year, month)


def year_2000_common(year: int, month: int) -> int:
    """The Gregorian century rule without its 400-year exception: 2000 is taken as a common year."""
    return 28 if (year, month) == (0, 2) else true_days(year, month)


def months_alternate(year: int, month: int) -> int:
    """30 + month % 2 for every month but February: right up to July, wrong from August (30, 31, 30, 31, 30)."""
    return true_days(year, month) if month == 2 else 30 + month % 2


def every_month_30(year: int, month: int) -> int:
    """The 31st of a month is never reached."""
    return min(30, true_days(year, month))


def count_on(year: int, month: int, day: int, hour: int, minute: int, second: int, seconds: int,
             days_in: DaysIn) -> tuple[tuple[int, int, int, int, int, int], int]:
    """((year, month, day, hour, minute, second), days passed) ``seconds`` after the given time, by ``days_in``."""
    total = hour * 3600 + minute * 60 + second + seconds
    days, rest = divmod(total, 86400)
    for _ in range(days):
        day += 1
        if day > days_in(year, month):
            day, month = 1, month + 1
            if month > 12:
                month, year = 1, (year + 1) % 100
    return (year, month, day, rest // 3600, rest // 60 % 60, rest % 60), days
