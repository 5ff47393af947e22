"""Times and durations for people: ``1005 d 18 h 07 min``, ``2026-12-01 20:15:38.770`` — never a bare count of
seconds since 1970 or a nine-digit offset."""

from __future__ import annotations

import datetime as dt


def span(seconds: float) -> str:
    """A duration without its sign: ``12.3 s``, ``4 min 05 s``, ``3 h 07 min``, ``1005 d 18 h 07 min``."""
    s = abs(seconds)
    if s < 60:
        return f"{s:.1f} s"
    whole = int(round(s))
    days, rest = divmod(whole, 86400)
    hours, rest = divmod(rest, 3600)
    minutes, secs = divmod(rest, 60)
    if days:
        return f"{days} d {hours} h {minutes:02d} min"
    if hours:
        return f"{hours} h {minutes:02d} min"
    return f"{minutes} min {secs:02d} s"


def moment(epoch: float) -> str:
    """A host time (seconds since the epoch) as local date and time to the millisecond."""
    when = dt.datetime.fromtimestamp(epoch)
    return f"{when:%Y-%m-%d %H:%M:%S}.{when.microsecond // 1000:03d}"
