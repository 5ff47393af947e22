"""The ``[rtc]`` section of an FBs bench profile: the emulator's RTC chip, crystal error and start time (on a real
bench, ``chip`` states what the PLC should report in D4053)."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any

from hil.bench.schema import Key, Section
from hil.core.errors import InvalidValue
from hil.families.fbs.rtc_time import CHIP_NAMES

CHIP_CODES = {name: code for code, name in CHIP_NAMES.items()}


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


RTC = Section("rtc", "The PLC's real-time clock: on a real bench chip states what D4053 should say; the rest "
              "configures the emulator's clock.", (
    Key("chip", object, "The RTC chip: 0 none, 1 HT1381, 2 ISL1208, 3 S-35390A (a name or its D4053 code).", 3,
        convert=_chip, default_doc="\"S-35390A\"", example="S-35390A",
        json={"anyOf": [{"type": "integer", "minimum": 0, "maximum": 3}, {"enum": list(CHIP_CODES)}]}),
    Key("crystal_ppm", float, "The emulated crystal's error (positive: the clock runs fast).", 0.0, low=-500,
        high=500, unit="ppm", hint="must be within ±500 ppm", live=False),
    Key("start", object, "The emulated clock at start: \"host\" (the host's time) or a date-time like "
        "2024-02-29 12:00:00.", convert=_start, default_doc="\"host\"", example="host", live=False,
        json={"type": "string"}),
    Key("drift_max_hours", float, "The longest one drift measurement may take on this bench (the drift test "
        "makes two, measuring until its resolution is below 0.088 s/day, and fails as inconclusive when this is "
        "not enough; 0: no drift test here).", 12.0, low=0, high=24 * 14, unit="h",
        hint="must be 0–336 h (0: no drift test here)"),
))


@dataclass(frozen=True)
class RtcSettings:
    """``[rtc]`` (:data:`RTC` describes each key)."""

    chip: int = RTC.default("chip")
    crystal_ppm: float = RTC.default("crystal_ppm")
    start: dt.datetime | None = RTC.default("start")  # None: the bench's host time when the emulator is built
    #: the longest one drift measurement may take on this bench (the drift test makes two); 0: none here
    drift_max_hours: float = RTC.default("drift_max_hours")


def parse_rtc(table: dict[str, Any], where: str) -> RtcSettings:
    return RtcSettings(**RTC.read(table, where))
