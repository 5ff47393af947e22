"""The running RTC across midnight (FBs manual ch. 15): set to the last second of a day, one bench second later
R4128–R4134 must show the next day — at the end of every month, of a leap and a common February, of 2000 and of a
year, the weekday advancing with the date.

Apart from test_rtc.py because of how it uses a serial line: a set (five round trips) every bench second.  In a run
with lanes on one line it runs right after the clock lane's busy modules, while the main lane waits
(hil.plugin.order).
"""

from __future__ import annotations

import datetime as dt

import pytest

#: every test sets the clock it relies on: the clock goes back (to its original offset from the bench's time) once,
#: after the last test here, not after each (hil.plugin.working_state)
# the clock lane: only the RTC suites touch the clock and M1952–M1955 (hil run --lanes); line="paced": a set every
# bench second, run after the lane's busy modules and before the rest, while the main lane waits (hil.plugin.order)
pytestmark = [pytest.mark.working_state("clock"), pytest.mark.lane("clock", line="paced")]


@pytest.mark.spec("RTC-RUN-1", "RTC-READ-1", "RTC-SET-2")
def test_clock_runs_over_every_month_end_and_midnight(bench, rtc, io):
    _midnights(bench, rtc, io, MIDNIGHTS)


#: The last second of a day → R4128–R4134 one second later, as the running clock must show it: the end of every
#: month (31-, 30-day months, 29 February), the 30th of a 31-day month (a clock that gives months 30 days fails
#: there), 28 February in a leap year, a common year and 2000 (the century year of the clock's range, a leap year),
#: the end of a year; the weekday advancing from Monday to Saturday.  Years chosen so that no case touches a Sunday
#: ([our choice] numbering, below).  Each case costs a bench second: one 30th, not every 31-day month's.
MIDNIGHTS = [
    ("2024-01-30 23:59:59", [0, 0, 0, 31, 1, 24, 3]),  # Tue → Wed
    ("2024-01-31 23:59:59", [0, 0, 0, 1, 2, 24, 4]),  # Wed → Thu
    ("2024-02-28 23:59:59", [0, 0, 0, 29, 2, 24, 4]),  # leap year: 28 → 29 February
    ("2024-02-29 23:59:59", [0, 0, 0, 1, 3, 24, 5]),  # Thu → Fri
    ("2023-02-28 23:59:59", [0, 0, 0, 1, 3, 23, 3]),  # common year: 28 February → 1 March
    ("2000-02-28 23:59:59", [0, 0, 0, 29, 2, 0, 2]),  # 2000 is a leap year (divisible by 400)
    ("2026-03-31 23:59:59", [0, 0, 0, 1, 4, 26, 3]),
    ("2024-04-30 23:59:59", [0, 0, 0, 1, 5, 24, 3]),
    ("2024-05-31 23:59:59", [0, 0, 0, 1, 6, 24, 6]),  # Fri → Sat
    ("2025-06-30 23:59:59", [0, 0, 0, 1, 7, 25, 2]),
    ("2024-07-31 23:59:59", [0, 0, 0, 1, 8, 24, 4]),
    ("2027-08-31 23:59:59", [0, 0, 0, 1, 9, 27, 3]),
    ("2024-09-30 23:59:59", [0, 0, 0, 1, 10, 24, 2]),
    ("2024-10-31 23:59:59", [0, 0, 0, 1, 11, 24, 5]),
    ("2026-11-30 23:59:59", [0, 0, 0, 1, 12, 26, 2]),
    ("2024-12-31 23:59:59", [0, 0, 0, 1, 1, 25, 3]),  # the end of a year
]
#: Saturday → Sunday (6 → 0), at a month end
SUNDAY_MIDNIGHTS = [
    ("2024-08-31 23:59:59", [0, 0, 0, 1, 9, 24, 0]),  # Sat → Sun
]


def _midnights(bench, rtc, io, cases: list[tuple[str, list[int]]]) -> None:
    """One bench second per case: the set restarts the chip's second, so one second after it the clock must have
    ticked into the next day — and not further than the time the procedure took."""
    wrong = []
    for when, after in cases:
        began = bench.time.now()
        assert rtc.set(dt.datetime.fromisoformat(when)).accepted, f"{when}: refused (M1955 = 1)"
        bench.wait(1.0)  # the set's edge came before this wait: the chip has ticked once by its end
        read = io.read_words("R4128", 7)
        most = int(bench.time.now() - began) - 1  # whole chip seconds past the tick, at most
        if read[1:] != after[1:] or not 0 <= read[0] <= max(most, 0):
            wrong.append(f"{when} + 1 s: R4128–R4134 = {read}, expected {after}")
    assert not wrong, "\n".join(wrong)


@pytest.mark.spec("RTC-RUN-1", "RTC-REG-4")
def test_clock_runs_into_and_out_of_a_sunday(bench, rtc, io):
    _midnights(bench, rtc, io, SUNDAY_MIDNIGHTS)
