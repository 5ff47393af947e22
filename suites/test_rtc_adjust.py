"""The ±30 s correction: on the rising edge of M1953, seconds 0–29 → :00, seconds 30–59 → :00 of the next
minute (FBs manual ch. 15).  The carry into hour, day, month and year is how a clock counts."""

from __future__ import annotations

import datetime as dt

import pytest

#: every test sets the clock it relies on: the clock goes back (to its original offset from the bench's time) once,
#: after the last test here, not after each (hil.plugin.working_state)
# the clock lane: only the RTC suites touch the clock and M1952–M1955 (hil run --lanes); line="busy": sets and
# read-backs back to back, run first in the lane, while the main lane waits (hil.plugin.order)
pytestmark = [pytest.mark.working_state("clock"), pytest.mark.lane("clock", line="busy")]


#: start → the time right after the M1953 edge: the window's every edge (00, 29 | 30, 59) within the minute.
WINDOWS = [
    ("2024-03-05 10:20:00", "2024-03-05 10:20:00"),  # first second of the "drop" window
    ("2024-03-05 10:20:10", "2024-03-05 10:20:00"),
    ("2024-03-05 10:20:29", "2024-03-05 10:20:00"),  # last second of the "drop" window
    ("2024-03-05 10:20:30", "2024-03-05 10:21:00"),  # first second of the "round up" window
    ("2024-03-05 10:20:45", "2024-03-05 10:21:00"),
    ("2024-03-05 10:20:59", "2024-03-05 10:21:00"),  # last second of the "round up" window
]
#: the added minute's carry into the hour and the day, and the day's into every month (each month's last day, the
#: 30th of a 31-day month, 28 and 29 February in a leap year, 28 February in a common year and in 2000) and year.
CARRIES = [
    ("2024-03-05 10:59:45", "2024-03-05 11:00:00"),  # minute → hour
    ("2024-01-30 23:59:30", "2024-01-31 00:00:00"),  # hour → day: the 30th of a 31-day month → the 31st
    ("2024-01-31 23:59:40", "2024-02-01 00:00:00"),
    ("2024-02-28 23:59:30", "2024-02-29 00:00:00"),  # leap year: 28 → 29 February
    ("2024-02-29 23:59:30", "2024-03-01 00:00:00"),  # leap day → March
    ("2023-02-28 23:59:30", "2023-03-01 00:00:00"),  # common year: February → March
    ("2000-02-28 23:59:30", "2000-02-29 00:00:00"),  # 2000 is a leap year
    ("2024-03-31 23:59:30", "2024-04-01 00:00:00"),
    ("2024-04-30 23:59:40", "2024-05-01 00:00:00"),  # 30-day month → next month
    ("2024-05-31 23:59:30", "2024-06-01 00:00:00"),
    ("2024-06-30 23:59:30", "2024-07-01 00:00:00"),
    ("2024-07-31 23:59:30", "2024-08-01 00:00:00"),
    ("2024-08-31 23:59:30", "2024-09-01 00:00:00"),
    ("2024-09-30 23:59:30", "2024-10-01 00:00:00"),
    ("2024-10-31 23:59:30", "2024-11-01 00:00:00"),
    ("2024-11-30 23:59:30", "2024-12-01 00:00:00"),
    ("2024-12-31 23:59:50", "2025-01-01 00:00:00"),  # month → year
    ("2098-12-31 23:59:30", "2099-01-01 00:00:00"),  # into the last year the chip counts: 2099, not a wrap
    ("2099-06-30 23:59:45", "2099-07-01 00:00:00"),  # a carry inside 2099 keeps 2099 (only 2099 → 2100 wraps)
]


def _correct(bench, rtc, begin: dt.datetime) -> float | None:
    """Set ``begin`` and fire M1953; the bench time the edge's procedure began, or None when three attempts all
    took longer than the chip stays in ``begin``'s window (a busy host)."""
    slack = 30 - begin.second % 30  # chip seconds before the next window boundary changes what the edge does
    for _attempt in range(3):
        with bench.exclusive():  # in a run with lanes: no other lane's request between the set and the edge
            before = bench.time.now()
            assert rtc.set(begin).accepted, f"{begin}: refused (M1955 = 1)"
            began = bench.time.now()
            rtc.adjust_30s()
        if bench.time.now() - before < slack:  # the edge surely came before the chip left the start's window
            return began
    return None


def _registers(when: dt.datetime) -> list[int]:
    """R4129–R4134 for ``when``: minute, hour, day, month, year, weekday (Python's calendar, 0 = Sunday)."""
    return [when.minute, when.hour, when.day, when.month, when.year - 2000, when.isoweekday() % 7]


def _check(bench, rtc, io, start: str, after: str, weekday: int | None = None) -> str | None:
    """None when the correction of ``start`` shows ``after`` (and ``weekday``, where the calendar's is not the
    clock's); else what is wrong (or why it was not tried)."""
    began = _correct(bench, rtc, dt.datetime.fromisoformat(start))
    if began is None:
        return f"not tried: {start}: the set and the M1953 edge took longer than the chip stays in its window"
    second, *rest = io.read_words("R4128", 7)
    ran = bench.time.now() - began  # from before the edge to after the read (a wire shared by lanes may wait)
    expected = _registers(dt.datetime.fromisoformat(after))
    if weekday is not None:
        expected[-1] = weekday
    # :00 at the edge, then the clock runs on until the read (a busy host's or a shared line's bench seconds)
    if rest != expected or not 0 <= second <= 1 + ran:
        return f"{start} → R4128–R4134 = {[second, *rest]}, expected {[0, *expected]} ({after})"
    return None


def _check_all(bench, rtc, io, cases: list[tuple[str, str]]) -> None:
    found = [_check(bench, rtc, io, start, after) for start, after in cases]
    wrong = [f for f in found if f and not f.startswith("not tried")]
    assert not wrong, "\n".join(wrong)
    untried = [f for f in found if f]
    if untried:
        pytest.skip("\n".join(untried) + ": lower [bench] time_scale on this host")


@pytest.mark.spec("RTC-ADJ-1", "RTC-ADJ-2")
def test_adjust_30s_over_both_windows_and_their_edges(bench, rtc, io):
    _check_all(bench, rtc, io, WINDOWS)


# the carry is the spec's [our choice] (RTC-ADJ-4), and its weekdays (Sundays too) numbered by RTC-REG-4: these
# tests need spec_choices (hil.plugin.requirements)
@pytest.mark.spec("RTC-ADJ-2", "RTC-ADJ-4", "RTC-REG-4")
def test_adjust_30s_carries_into_hour_day_every_month_and_year(bench, rtc, io):
    _check_all(bench, rtc, io, CARRIES)


@pytest.mark.spec("RTC-ADJ-2", "RTC-ADJ-4", "RTC-ADJ-5", "RTC-RUN-3")
def test_adjust_30s_carry_from_2099_wraps_to_2000(bench, rtc, io):
    """The weekday is the chip's own counter: Thursday 31 December 2099 (4) → Friday (5), one day on, although the
    calendar's 1 January 2000 was a Saturday."""
    problem = _check(bench, rtc, io, "2099-12-31 23:59:30", "2000-01-01 00:00:00", weekday=5)
    if problem and problem.startswith("not tried"):
        pytest.skip(problem + ": lower [bench] time_scale on this host")
    assert problem is None, problem


@pytest.mark.spec("RTC-ADJ-3", "RTC-ADJ-2")
def test_adjust_acts_on_the_rising_edge_only(bench, rtc, io):
    assert rtc.set(dt.datetime(2024, 3, 5, 10, 20, 40)).accepted
    began = bench.time.now()
    io.write("M1953", 1)  # rising edge: 10:20:40 → 10:21:00
    bench.settle()
    second, minute, hour = io.read_words("R4128", 3)
    most = int(bench.time.now() - began) + 1  # the clock runs on from :00 while the edge and the read take their time
    assert (hour, minute) == (10, 21) and 0 <= second <= most, f"the edge did not correct: {hour}:{minute}:{second}"
    # M1953 still held at 1 while the clock shows a second in the 30–59 window: a PLC acting on the level
    # rather than the edge would round it up to 10:22:00 at its next scan
    began = bench.time.now()
    assert rtc.set(dt.datetime(2024, 3, 5, 10, 21, 45)).accepted
    bench.wait(1)
    io.write("M1953", 0)
    second, minute, hour = io.read_words("R4128", 3)
    most = 45 + int(bench.time.now() - began) + 1  # the set, the wait and the requests, on a busy host too
    assert (hour, minute) == (10, 21), f"corrected again while M1953 stayed 1: {hour}:{minute}:{second}"
    assert 46 <= second <= max(48, most), f"second {second}: the clock did not run on from 10:21:45"
