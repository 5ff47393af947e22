"""The ``[rtc]`` section of an FBs bench profile: the emulator's RTC chip, crystal error and start time (on a real
bench, ``chip`` states what the PLC should report in D4053)."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any

from hil.core.errors import InvalidValue
from hil.bench.profile import Reader
from hil.families.fbs.rtc_time import CHIP_NAMES

CHIP_CODES = {name: code for code, name in CHIP_NAMES.items()}


@dataclass(frozen=True)
class RtcSettings:
    chip: int = 3
    crystal_ppm: float = 0.0
    start: dt.datetime | None = None  # None: the bench's host time when the emulator is built
    #: the longest one drift measurement may take on this bench (the drift test makes two); 0: none here
    drift_max_hours: float = 12.0


def parse_rtc(table: dict[str, Any], where: str) -> RtcSettings:
    reader = Reader(where)
    table = dict(table)
    settings = RtcSettings(
        chip=reader.take(table, "rtc", "chip", object, 3, convert=_chip),
        crystal_ppm=reader.take(table, "rtc", "crystal_ppm", float, 0.0,
                                check=lambda v: abs(v) <= 500 or "must be within ±500 ppm"),
        start=reader.take(table, "rtc", "start", object, None, convert=_start),
        drift_max_hours=reader.take(table, "rtc", "drift_max_hours", float, 12.0,
                                    check=lambda v: 0 <= v <= 24 * 14 or "must be 0–336 h (0: no drift test here)"))
    reader.done(table, "rtc")
    return settings


def _chip(value: Any) -> int:
    if isinstance(value, int) and not isinstance(value, bool) and value in CHIP_NAMES:
        return value
    if isinstance(value, str) and value in CHIP_CODES:
        return CHIP_CODES[value]
    raise InvalidValue(f"chip must be 0–3 or one of {', '.join(CHIP_CODES)}, not {value!r}")


def _start(value: Any) -> dt.datetime | None:
    if isinstance(value, dt.datetime):
        return value.replace(tzinfo=None)
    if value == "host":
        return None
    if isinstance(value, str):
        return dt.datetime.fromisoformat(value)
    raise InvalidValue(f"start must be 'host' or a date-time like '2024-02-29 12:00:00', not {value!r}")
