"""RtcTime: register mapping, R4135, validity rules of the FBs clock, weekday numbering (0 = Sunday)."""

from __future__ import annotations

import dataclasses
import datetime as dt

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hil.families.fbs.rtc_time import RtcTime, days_in_month, is_leap, weekday_of

VALID = RtcTime(second=5, minute=45, hour=13, day=29, month=2, year=24, weekday=4)  # Thu 29 Feb 2024


def test_datetime_round_trip_and_weekday() -> None:
    t = RtcTime.from_datetime(dt.datetime(2024, 2, 29, 13, 45, 5, 999_999))
    assert t == VALID  # sub-seconds dropped, weekday from the date
    assert t.to_datetime() == dt.datetime(2024, 2, 29, 13, 45, 5)


@pytest.mark.parametrize(("date", "weekday"), [
    (dt.date(2000, 1, 1), 6),  # Saturday
    (dt.date(2024, 3, 3), 0),  # Sunday
    (dt.date(2024, 3, 4), 1),  # Monday
    (dt.date(2099, 12, 31), 4),  # Thursday
])
def test_weekday_zero_is_sunday(date: dt.date, weekday: int) -> None:
    assert weekday_of(date.year - 2000, date.month, date.day) == weekday
    assert RtcTime.from_datetime(dt.datetime.combine(date, dt.time())).weekday == weekday


def test_register_order_second_first() -> None:
    assert VALID.to_registers() == [5, 45, 13, 29, 2, 24, 4]
    assert RtcTime.from_registers([5, 45, 13, 29, 2, 24, 4]) == VALID
    with pytest.raises(ValueError, match="7 registers"):
        RtcTime.from_registers([1, 2, 3])


def test_hour_minute_word() -> None:
    assert VALID.hour_minute_word() == 0x0D2D  # the spec's 13:45 example
    assert dataclasses.replace(VALID, hour=23, minute=59).hour_minute_word() == 23 << 8 | 59


@pytest.mark.parametrize("year", [1999, 2100])
def test_years_outside_the_chip_are_refused(year: int) -> None:
    with pytest.raises(ValueError, match="2000–2099"):
        RtcTime.from_datetime(dt.datetime(year, 6, 1))


@pytest.mark.parametrize(("changes", "fields"), [
    ({"second": 60}, ["second"]),
    ({"minute": 60}, ["minute"]),
    ({"hour": 24}, ["hour"]),
    ({"day": 0}, ["day"]),
    ({"month": 4, "day": 31}, ["day"]),  # 31 April
    ({"year": 23, "month": 2, "day": 29}, ["day"]),  # 29 Feb in a non-leap year
    ({"month": 0}, ["month"]),
    ({"month": 13}, ["month"]),
    ({"year": 100}, ["year"]),
    ({"weekday": 7}, ["weekday"]),
    ({"second": 0xFFFF}, ["second"]),  # a "negative" write is a large unsigned value
    ({"second": 60, "minute": 60, "hour": 24, "day": 32, "month": 13, "year": 100, "weekday": 7},
     ["second", "minute", "hour", "day", "month", "year", "weekday"]),
])
def test_validate_names_every_invalid_field(changes: dict, fields: list[str]) -> None:
    t = dataclasses.replace(VALID, **changes)
    assert t.validate() == fields
    assert not t.is_valid
    with pytest.raises(ValueError, match=fields[0]):
        t.to_datetime()


def test_weekday_is_range_checked_not_matched_to_the_date() -> None:
    assert dataclasses.replace(VALID, weekday=0).validate() == []


def test_leap_years_of_the_two_digit_century() -> None:
    assert is_leap(0) and is_leap(24) and not is_leap(23) and not is_leap(99)
    assert days_in_month(24, 2) == 29 and days_in_month(23, 2) == 28
    assert days_in_month(0, 2) == 29  # 2000 is a leap year
    assert [days_in_month(1, m) for m in range(1, 13)] == [31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31]


@given(st.datetimes(min_value=dt.datetime(2000, 1, 1), max_value=dt.datetime(2099, 12, 31, 23, 59, 59)))
def test_every_datetime_of_the_century_round_trips(when: dt.datetime) -> None:
    t = RtcTime.from_datetime(when)
    assert t.validate() == []
    assert RtcTime.from_registers(t.to_registers()) == t
    assert t.to_datetime() == when.replace(microsecond=0)
    assert t.weekday == (when.weekday() + 1) % 7
