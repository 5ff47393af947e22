"""RTC set / read-out through M1952 and R4128–R4135 (FBs manual ch. 15).

R4128 second · R4129 minute · R4130 hour · R4131 day · R4132 month · R4133 year (0–99 = 2000–2099) ·
R4134 weekday (0 = Sunday) · R4135 = hour<<8 | minute.  Set: M1952 := 1, write R4128–R4134, M1952 := 0.
Each expectation below is written out as the manual states it; a second may tick between a set and a read,
so seconds are allowed one step.
"""

from __future__ import annotations

import datetime as dt

import pytest


def at(text: str) -> dt.datetime:
    return dt.datetime.fromisoformat(text)


@pytest.mark.spec("RTC-REG-1", "RTC-REG-3", "RTC-SET-1", "RTC-SET-2", "RTC-SET-3", "RTC-VAL-3")
@pytest.mark.parametrize("when, registers", [
    # second, minute, hour, day, month, year, weekday
    ("2024-02-29 12:34:56", [56, 34, 12, 29, 2, 24, 4]),  # leap day, a Thursday
    ("2000-01-01 00:00:00", [0, 0, 0, 1, 1, 0, 6]),  # first day the chip can hold, a Saturday
    ("2099-12-31 23:59:00", [0, 59, 23, 31, 12, 99, 4]),  # last day, a Thursday
    # a Sunday: weekday 0 is the spec's [our choice] of numbering (a PLC counting 1–7 refuses it)
    pytest.param("2023-07-09 07:05:03", [3, 5, 7, 9, 7, 23, 0], marks=pytest.mark.spec("RTC-REG-4")),
])
def test_set_then_read_round_trip(rtc, io, when, registers):
    assert rtc.set(at(when)).accepted
    read = io.read_words("R4128", 7)
    assert read[1:] == registers[1:]
    assert read[0] in (registers[0], registers[0] + 1)


@pytest.mark.spec("RTC-RUN-1", "RTC-SET-2")
def test_clock_keeps_running_after_a_set(bench, rtc, io):
    assert rtc.set(at("2024-03-05 10:00:00")).accepted
    bench.wait(10)
    second, minute, hour = io.read_words("R4128", 3)
    assert (hour, minute) == (10, 0)
    assert second in (10, 11)


@pytest.mark.spec("RTC-RUN-2")  # [our choice]: needs spec_choices
def test_end_of_2099_rolls_over_to_2000(bench, rtc, io):
    assert rtc.set(at("2099-12-31 23:59:59")).accepted
    bench.wait(2)
    second, minute, hour, day, month, year = io.read_words("R4128", 6)
    assert (minute, hour, day, month, year) == (0, 0, 1, 1, 0)
    assert second in (1, 2)


@pytest.mark.spec("RTC-RUN-1")
def test_weekday_advances_at_midnight(bench, rtc, io):
    assert rtc.set(at("2024-03-05 23:59:58")).accepted  # Tuesday
    bench.wait(3)
    second, minute, hour, day, month, year, weekday = io.read_words("R4128", 7)
    assert (minute, hour, day, month, year) == (0, 0, 6, 3, 24)
    assert weekday == 3  # Wednesday
    assert second in (1, 2)


@pytest.mark.spec("RTC-REG-2", "RTC-READ-1")
@pytest.mark.parametrize("when, word", [("2024-03-05 13:45:10", 0x0D2D), ("2024-03-05 09:05:00", 0x0905),
                                        ("2024-03-05 23:59:00", 0x173B), ("2024-03-05 00:00:30", 0x0000)])
def test_r4135_is_hour_high_byte_minute_low_byte(rtc, io, when, word):
    assert rtc.set(at(when)).accepted
    assert io.read("R4135") == word


@pytest.mark.spec("RTC-READ-1", "RTC-SET-3")
def test_read_out_overwrites_registers_while_m1952_is_0(bench, rtc, io):
    assert rtc.set(at("2024-03-05 10:00:00")).accepted
    io.write_words("R4133", [50])  # year 2050 written while M1952 = 0 …
    bench.settle()
    assert io.read("R4133") == 24  # … is overwritten by the clock's year on the next scan


@pytest.mark.spec("RTC-READ-2", "RTC-SET-1", "RTC-SET-2")
def test_registers_freeze_while_m1952_is_1_and_follow_again_after(bench, rtc, io):
    assert rtc.set(at("2024-05-10 08:00:00")).accepted
    io.write("M1952", 1)
    bench.settle()
    frozen = io.read_words("R4128", 7)
    bench.wait(3)
    assert io.read_words("R4128", 7) == frozen, "R4128–R4134 changed while M1952 = 1"

    io.write_words("R4128", [30, 20, 10, 4, 7, 30, 4])  # 2030-07-04 10:20:30, a Thursday
    bench.wait(3)
    assert io.read_words("R4128", 7) == [30, 20, 10, 4, 7, 30, 4], "written values did not stay put"

    io.write("M1952", 0)  # falling edge: the PLC sets the clock from R4128–R4134
    bench.settle()
    bench.wait(2)
    second, *rest = io.read_words("R4128", 7)
    assert rest == [20, 10, 4, 7, 30, 4]
    assert second in (32, 33), "read-out did not resume from the time that was set"


@pytest.mark.spec("RTC-CHIP-1", "RTC-FLAG-1")
def test_rtc_fitted_flag_m1954_matches_the_chip(bench, io):
    expected_chip = bench.profile.rtc.chip if bench.profile.rtc else None
    if bench.unreachable_reason("D4053") is None:
        chip = io.read("D4053")
        if expected_chip is not None:
            assert chip == expected_chip, f"D4053 = {chip}, the bench profile says {expected_chip}"
    elif expected_chip is not None:
        chip = expected_chip  # D4053 unreachable on this wire: check M1954 against the profile instead
    else:
        pytest.skip(f"D4053 unreachable ({bench.unreachable_reason('D4053')}) and the profile has no [rtc]")
    assert io.read("M1954") == (1 if chip != 0 else 0)
