"""RTC set validation: an invalid time is not set, M1955 = 1, and the clock runs on (FBs manual ch. 15).

Every case starts from a clock set to 2024-06-15 08:00:00 (a Saturday) and tries to set registers
R4128–R4134 = second, minute, hour, day, month, year, weekday with exactly one field wrong: one past each
field's minimum and maximum, every month's day one past its last (31 in each 30-day month, 32, 29 and 30
February), and for every field each way an unsigned 16-bit register is out of range that a narrower check would
miss (the sign bit set, FFFFH, the high byte set over a valid low byte).  The
refusals follow each other with no wait, each against the clock set to START (set again every 30 s); one wait
at the end shows the clock still running.
"""

from __future__ import annotations

import datetime as dt

import pytest

from hil.families.fbs.rtc_time import FIELDS, RtcTime

#: every test sets the clock it relies on: the clock goes back (to its original offset from the bench's time) once,
#: after the last test here, not after each (hil.plugin.working_state)
# the clock lane: only the RTC suites touch the clock and M1952–M1955 (hil run --lanes); line="busy": sets and
# read-backs back to back, run first in the lane, while the main lane waits (hil.plugin.order)
pytestmark = [pytest.mark.working_state("clock"), pytest.mark.lane("clock", line="busy")]

START = dt.datetime(2024, 6, 15, 8, 0, 0)
#: R4129–R4134 of START: minute, hour, day, month, year, weekday (a Saturday)
START_REST = [0, 8, 15, 6, 24, 6]

#: R4128–R4134 of the valid time the register-width cases break one field of: 2024-06-20 09:00:00, a Thursday
VALID = [0, 0, 9, 20, 6, 24, 4]


def _out_of_register_range(fields: tuple[str, ...]) -> dict[str, RtcTime]:
    """Each of ``fields`` out of range in every way a 16-bit unsigned register can be while a narrower check would
    pass it: the sign bit set over a valid value (8000H + v: "negative", below any maximum if compared signed),
    FFFFH (−1 signed, its low byte FFH out of range too) and the high byte set over a valid low byte (0100H + v:
    valid if only the low byte is checked).  The other fields stay those of VALID."""
    cases = {}
    for field in fields:
        index = FIELDS.index(field)
        valid = VALID[index]
        for wrong, kind in ((0x8000 + valid, f"sign bit over {valid}"), (0xFFFF, "-1"),
                            (0x0100 + valid, f"low byte {valid}")):
            registers = list(VALID)
            registers[index] = wrong
            cases[f"{field} {wrong:04X}H ({kind})"] = RtcTime.from_registers(registers)
    return cases


INVALID = {
    "second 60": RtcTime(60, 0, 9, 20, 6, 24, 4),
    "minute 60": RtcTime(0, 60, 9, 20, 6, 24, 4),
    "hour 24": RtcTime(0, 0, 24, 20, 6, 24, 4),
    "day 0": RtcTime(0, 0, 9, 0, 6, 24, 4),
    "day 32 January": RtcTime(0, 0, 9, 32, 1, 24, 4),
    "31 April": RtcTime(0, 0, 9, 31, 4, 24, 3),
    "31 June": RtcTime(0, 0, 9, 31, 6, 24, 1),
    "31 September": RtcTime(0, 0, 9, 31, 9, 24, 2),
    "31 November": RtcTime(0, 0, 9, 31, 11, 24, 1),
    "30 February 2024 (leap)": RtcTime(0, 0, 9, 30, 2, 24, 5),
    "29 February 2023": RtcTime(0, 0, 9, 29, 2, 23, 3),
    "29 February 2099": RtcTime(0, 0, 9, 29, 2, 99, 1),
    "month 0": RtcTime(0, 0, 9, 20, 0, 24, 4),
    "month 13": RtcTime(0, 0, 9, 20, 13, 24, 4),
    "year 100": RtcTime(0, 0, 9, 20, 6, 100, 4),
    **_out_of_register_range(("second", "minute", "hour", "day", "month", "year")),
}
#: the weekday's range is the spec's [our choice] (RTC-VAL-5): checked apart, on a bench that offers spec_choices
INVALID_WEEKDAY = {
    "weekday 7": RtcTime(0, 0, 9, 20, 6, 24, 7),
    **_out_of_register_range(("weekday",)),
}


#: bench seconds after a set of START within which its minute (R4129) and hour still read START's: the cases are
#: refused against one set of START until then (a refused set leaves the clock on it), well before the minute turns
START_HOLDS_S = 30.0


def _refuse_each(bench, rtc, io, cases: dict[str, RtcTime]) -> None:
    """Per case: the invalid set — M1955 must be 1 after it and R4128–R4134 still on START's time, set before the
    case (again after START_HOLDS_S, or after a case that changed the clock).  No wait between cases; after the last
    refusal one wait: the clock must have run on from START.

    Whether an accepted set clears M1955 is the spec's [our choice] (RTC-VAL-4), not relied on here: where START's
    set leaves M1955 at 1, the clock left unchanged is the evidence of that case's refusal."""
    wrong = []
    began = None
    for case, registers in cases.items():
        if began is None or bench.time.now() - began > START_HOLDS_S:
            began = bench.time.now()
            rtc.set(START)
        result = rtc.set(registers)
        shown = result.shown  # R4128–R4134, read with M1955 from a scan after the set
        # the chip restarted its second at START's set, after `began`: on START's time, run on by at most the whole
        # seconds since (a case may wait long for a shared line: the minute may have turned)
        most = dt.timedelta(seconds=int(bench.time.now() - began) + 1)
        if result.accepted:
            wrong.append(f"{case}: M1955 = 0 after the set")
        if not _on_start_time(shown, most):
            wrong.append(f"{case}: the clock was changed: R4128–R4134 = {shown.to_registers()}")
            began = None  # (START again for the next case)
    assert not wrong, "\n".join(wrong)
    bench.wait(1.2)
    shown = RtcTime.from_registers(io.read_words("R4128", 7))
    # START's last set came after `began`: at most the whole seconds since then (+ the one the chip restarted),
    # however long the requests took; at least the 1.2 s waited since
    most = dt.timedelta(seconds=int(bench.time.now() - began) + 1)
    assert _on_start_time(shown, most, least=dt.timedelta(seconds=1)), (
        f"after the refusals the clock stopped or jumped: R4128–R4134 = {shown.to_registers()} "
        f"{bench.time.now() - began:.1f} s after START's last set began")


def _on_start_time(shown: RtcTime, most: dt.timedelta, least: dt.timedelta = dt.timedelta(0)) -> bool:
    """The clock shows START run on by ``least`` to ``most``, START's weekday kept (no midnight in between)."""
    try:
        when = shown.to_datetime()
    except ValueError:  # (registers that are no date at all: certainly not START's time)
        return False
    return START + least <= when <= START + most and shown.weekday == START_REST[-1]


@pytest.mark.spec("RTC-VAL-1", "RTC-VAL-2", "RTC-VAL-3", "RTC-REG-3")
def test_every_invalid_field_is_refused_with_m1955_and_the_clock_runs_on(bench, rtc, io):
    _refuse_each(bench, rtc, io, INVALID)


@pytest.mark.spec("RTC-VAL-5", "RTC-VAL-1")
def test_weekday_out_of_range_is_refused_with_m1955_and_the_clock_runs_on(bench, rtc, io):
    _refuse_each(bench, rtc, io, INVALID_WEEKDAY)


@pytest.mark.spec("RTC-VAL-4", "RTC-VAL-3")  # an accepted set clearing M1955 is [our choice]
def test_valid_set_after_a_refused_one_clears_m1955(rtc, io):
    assert rtc.set(INVALID["31 April"]).refused  # M1955 = 1
    assert rtc.set(dt.datetime(2024, 4, 30, 12, 0, 0)).accepted  # M1955 = 0 again
    snapshot = rtc.read_all()  # R4128–R4135 and M1952–M1955 in one round trip
    assert snapshot.flags.set_error is False, "M1955 did not stay 0"
    assert snapshot.time.to_registers()[1:6] == [0, 12, 30, 4, 24]  # R4129–R4133


#: 29 February of 2000 (the century year), of the leap years up to 2016 (any period of the leap rule up to 16
#: years shows there) and of 2096 (the last); 2004 is a Sunday (weekday 0: [our choice], RTC-REG-4) and apart
LEAP_YEARS = [0, 8, 12, 16, 96]
SUNDAY_LEAP_YEARS = [4]


def _leap_days(rtc, io, years: list[int]) -> None:
    wrong = []
    for year in years:
        result = rtc.set(dt.datetime(2000 + year, 2, 29, 6, 30, 0))
        shown = result.shown.to_registers()[1:6]  # R4129–R4133, read with M1955 from a scan after the set
        if not result.accepted or shown != [30, 6, 29, 2, year]:
            wrong.append(f"29 February {2000 + year}: M1955 = {int(result.refused)}, R4129–R4133 = {shown}")
    assert not wrong, "\n".join(wrong)


@pytest.mark.spec("RTC-VAL-3", "RTC-REG-3")
def test_leap_day_accepted_in_leap_years_2000_to_2096(rtc, io):
    _leap_days(rtc, io, LEAP_YEARS)


@pytest.mark.spec("RTC-VAL-3", "RTC-REG-4")
def test_leap_day_accepted_in_the_leap_years_it_is_a_sunday(rtc, io):
    _leap_days(rtc, io, SUNDAY_LEAP_YEARS)
