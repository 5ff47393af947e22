"""RTC set validation: an invalid time is not set, M1955 = 1, and the clock runs on (FBs manual ch. 15).

Every case starts from a clock set to 2024-06-15 08:00:00 (a Saturday) and tries to set registers
R4128–R4134 = second, minute, hour, day, month, year, weekday with exactly one field wrong.
"""

from __future__ import annotations

import datetime as dt

import pytest

from hil.families.fbs.rtc_time import RtcTime

START = dt.datetime(2024, 6, 15, 8, 0, 0)

INVALID = {
    "second 60": RtcTime(60, 0, 9, 20, 6, 24, 4),
    "minute 60": RtcTime(0, 60, 9, 20, 6, 24, 4),
    "hour 24": RtcTime(0, 0, 24, 20, 6, 24, 4),
    "day 0": RtcTime(0, 0, 9, 0, 6, 24, 4),
    "31 April": RtcTime(0, 0, 9, 31, 4, 24, 3),
    "29 February 2023": RtcTime(0, 0, 9, 29, 2, 23, 3),
    "30 February 2024": RtcTime(0, 0, 9, 30, 2, 24, 5),
    "month 0": RtcTime(0, 0, 9, 20, 0, 24, 4),
    "month 13": RtcTime(0, 0, 9, 20, 13, 24, 4),
    "year 100": RtcTime(0, 0, 9, 20, 6, 100, 4),
    "weekday 7": RtcTime(0, 0, 9, 20, 6, 24, 7),
    "negative second (FFFFH)": RtcTime(0xFFFF, 0, 9, 20, 6, 24, 4),
}


#: what each case checks beyond RTC-VAL-1 (refused, M1955 = 1, the clock runs on)
CHECKS = {"31 April": "RTC-VAL-3", "29 February 2023": "RTC-VAL-3", "30 February 2024": "RTC-VAL-3",
          "weekday 7": "RTC-VAL-5"}  # weekday 0–6 is the spec's [our choice] (needs spec_choices)


@pytest.mark.spec("RTC-VAL-1")
@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.spec(CHECKS.get(c, "RTC-VAL-2")), id=c)
                                  for c in INVALID])
def test_invalid_time_is_refused_with_m1955_and_clock_runs_on(bench, rtc, io, case):
    assert rtc.set(START).accepted  # .accepted is M1955 = 0, read after the set
    began = bench.time.now()  # the chip restarted its second at the set, before this
    assert rtc.set(INVALID[case]).refused, f"{case}: M1955 not set"  # .refused is M1955 = 1
    bench.wait(1)
    second, minute, hour, day, month, year, weekday = io.read_words("R4128", 7)
    ran = bench.time.now() - began  # at least this long since the chip's restart (a busy host makes it longer)
    assert (minute, hour, day, month, year, weekday) == (0, 8, 15, 6, 24, 6), f"{case}: the clock was changed"
    assert 1 <= second and int(ran) - 1 <= second <= int(ran) + 2, (
        f"{case}: the clock stopped or jumped (second = {second} after {ran:.1f} s)")


@pytest.mark.spec("RTC-VAL-4", "RTC-VAL-3")  # an accepted set clearing M1955 is [our choice]
def test_valid_set_after_a_refused_one_clears_m1955(rtc, io):
    assert rtc.set(INVALID["31 April"]).refused  # M1955 = 1
    assert rtc.set(dt.datetime(2024, 4, 30, 12, 0, 0)).accepted  # M1955 = 0 again
    snapshot = rtc.read_all()  # R4128–R4135 and M1952–M1955 in one round trip
    assert snapshot.flags.set_error is False, "M1955 did not stay 0"
    assert snapshot.time.to_registers()[1:6] == [0, 12, 30, 4, 24]  # R4129–R4133


@pytest.mark.spec("RTC-VAL-3", "RTC-REG-3")
def test_leap_day_accepted_in_a_leap_year(rtc, io):
    assert rtc.set(dt.datetime(2028, 2, 29, 6, 30, 0)).accepted
    assert io.read("M1955") == 0
    assert io.read_words("R4129", 5) == [30, 6, 29, 2, 28]
