"""RTC set / read-out through M1952 and R4128–R4135 (FBs manual ch. 15).

R4128 second · R4129 minute · R4130 hour · R4131 day · R4132 month · R4133 year (0–99 = 2000–2099) ·
R4134 weekday (0 = Sunday) · R4135 = hour<<8 | minute.  Set: M1952 := 1, write R4128–R4134, M1952 := 0.
Each expectation below is written out as the manual states it; a second may tick between a set and a read,
so seconds are allowed one step.
"""

from __future__ import annotations

import datetime as dt

import pytest

from hil.families.fbs.device.rtc import RtcSetLost
from hil.families.fbs.rtc_time import RtcTime

#: every test sets the clock it relies on: the clock goes back (to its original offset from the bench's time) once,
#: after the last test here, not after each (hil.plugin.working_state)
# the clock lane: only the RTC suites touch the clock and M1952–M1955 (hil run --lanes); line="idle": mostly waits
# for the clock's seconds, run after the lane's busy modules (hil.plugin.order)
pytestmark = [pytest.mark.working_state("clock"), pytest.mark.lane("clock", line="idle")]


def at(text: str) -> dt.datetime:
    return dt.datetime.fromisoformat(text)


#: second, minute, hour, day, month, year, weekday as the manual's registers hold them.  Together: every field at
#: its minimum and its maximum, every weekday 1–6, a leap day.  A second may tick between the set and the read.
#: (Sunday = 0 is the spec's [our choice] of numbering, RTC-REG-4: its cases are apart, below.)
ROUND_TRIPS = [
    ("2000-01-01 00:00:00", [0, 0, 0, 1, 1, 0, 6]),  # every field at its minimum (the first day), a Saturday
    ("2099-12-31 23:59:58", [58, 59, 23, 31, 12, 99, 4]),  # every field at its maximum (the last day), a Thursday
    ("2024-02-29 12:34:59", [59, 34, 12, 29, 2, 24, 4]),  # leap day, second 59, a Thursday
    ("2023-07-10 19:45:30", [30, 45, 19, 10, 7, 23, 1]),  # a Monday
    ("2030-09-17 01:10:20", [20, 10, 1, 17, 9, 30, 2]),  # a Tuesday
    ("2041-11-20 22:58:07", [7, 58, 22, 20, 11, 41, 3]),  # a Wednesday
    ("2077-03-26 16:00:44", [44, 0, 16, 26, 3, 77, 5]),  # a Friday
]
SUNDAY_ROUND_TRIPS = [("2023-07-09 07:05:03", [3, 5, 7, 9, 7, 23, 0])]


def _one_second_on(registers: list[int]) -> list[int]:
    """The registers one second later, for the second that may tick between a set and its read (only within the
    minute: the cases above never carry further)."""
    second, minute, *rest = registers
    return [second + 1, minute, *rest] if second < 59 else [0, minute + 1, *rest]


def _round_trips(rtc, io, cases: list[tuple[str, list[int]]]) -> None:
    wrong = []
    for when, registers in cases:
        result = rtc.set(at(when))
        assert result.accepted, f"{when}: refused (M1955 = 1)"
        read = result.shown.to_registers()  # R4128–R4134, read with M1955 from a scan after the set
        if read not in (registers, _one_second_on(registers)):
            wrong.append(f"{when}: R4128–R4134 = {read}, expected {registers}")
    assert not wrong, "\n".join(wrong)


@pytest.mark.spec("RTC-SET-1", "RTC-SET-3", "RTC-REG-1", "RTC-REG-3", "RTC-VAL-3")
def test_set_then_read_round_trip_of_every_field_edge_and_weekday(rtc, io):
    _round_trips(rtc, io, ROUND_TRIPS)


@pytest.mark.spec("RTC-SET-1", "RTC-REG-1", "RTC-REG-4")
def test_set_then_read_round_trip_of_a_sunday(rtc, io):
    _round_trips(rtc, io, SUNDAY_ROUND_TRIPS)


@pytest.mark.spec("RTC-RUN-1", "RTC-SET-2")
def test_clock_keeps_running_after_a_set(bench, rtc, io):
    """The rate to ±20 % over 5 s (the month-end test sees every bench second bring exactly one tick; the slow
    drift tests measure the rate to 0.088 s/day)."""
    began = bench.time.now()
    assert rtc.set(at("2024-03-05 10:00:00")).accepted
    bench.wait(5)
    second, minute, hour = io.read_words("R4128", 3)
    most = int(bench.time.now() - began) + 1  # the set's procedure, the wait and the read, on a busy host too
    assert (hour, minute) == (10, 0)
    assert 5 <= second <= max(6, most), f"second {second} 5 s after a set of 10:00:00"


@pytest.mark.spec("RTC-RUN-2", "RTC-RUN-3")  # [our choice]: needs spec_choices
def test_end_of_2099_rolls_over_to_2000(bench, rtc, io):
    """The weekday counts on: Thursday 31 December 2099 (4) → Friday (5), although 1 January 2000 was a Saturday."""
    began = bench.time.now()
    assert rtc.set(at("2099-12-31 23:59:59")).accepted
    bench.wait(2)
    second, minute, hour, day, month, year, weekday = io.read_words("R4128", 7)
    most = int(bench.time.now() - began)  # whole seconds past 23:59:59, however long the set and the read took
    assert (minute, hour, day, month, year) == (0, 0, 1, 1, 0)
    assert 1 <= second <= max(2, most), f"second {second} 2 s after a set of 23:59:59"
    assert weekday == 5, f"R4134 = {weekday} after Thursday 31 December 2099, expected 5 (Friday, one day on)"


@pytest.mark.spec("RTC-VAL-5", "RTC-RUN-3")  # [our choice]: needs spec_choices
def test_weekday_written_is_kept_and_counts_on_from_itself(bench, rtc, io):
    """The weekday is the chip's own counter, never computed from the date: a Thursday (29 February 2024) written
    as Monday (1) is taken as written, and at midnight it counts on to Tuesday (2), not to the date's Friday."""
    sent = RtcTime(59, 59, 23, 29, 2, 24, 1)
    began = bench.time.now()
    result = rtc.set(sent)
    assert result.accepted, f"{sent}: refused (M1955 = 1): the weekday is not checked against the date"
    assert result.shown.weekday == 1, f"R4134 = {result.shown.weekday} after a set of weekday 1 on a Thursday"
    bench.wait(1.0)  # the chip restarted its second at the set: it has ticked into 1 March by now
    read = io.read_words("R4128", 7)
    most = int(bench.time.now() - began) - 1
    assert read[1:] == [0, 0, 1, 3, 24, 2] and 0 <= read[0] <= max(most, 0), (
        f"R4128–R4134 = {read} one second after {sent}: expected [0, 0, 0, 1, 3, 24, 2] (Tuesday, one day on from "
        f"the Monday written)")


#: (time set, R4135 expected): hour and minute each at both ends and between, and a pair whose bytes differ
R4135_CASES = [("2024-03-05 13:45:10", 0x0D2D), ("2024-03-05 09:05:00", 0x0905), ("2024-03-05 23:59:00", 0x173B),
               ("2024-03-05 00:00:30", 0x0000)]


@pytest.mark.spec("RTC-REG-2", "RTC-READ-1")
def test_r4135_is_hour_high_byte_minute_low_byte(rtc, io):
    """R4135 = hour × 256 + minute, one set after another (the clock put back once, when the test ends)."""
    wrong = []
    for when, word in R4135_CASES:
        assert rtc.set(at(when)).accepted, f"{when}: refused (M1955 = 1)"
        got = io.read("R4135")
        if got != word:
            wrong.append(f"{when}: R4135 = {got:04X}H, expected {word:04X}H (hour high byte, minute low byte)")
    assert not wrong, "; ".join(wrong)


#: (time set, R4135 one tick later): the running clock's second 59 carrying into the minute, the hour, a new day
R4135_RUNNING = [("2024-03-05 13:45:59", 0x0D2E), ("2024-03-05 09:59:59", 0x0A00),
                 ("2024-03-05 23:59:59", 0x0000)]


@pytest.mark.spec("RTC-REG-2", "RTC-READ-1")
def test_r4135_follows_the_running_clock_across_a_minute_an_hour_and_midnight(bench, rtc, io):
    """R4135 is read out every scan with R4128–R4134, not only written at a set: a second after each set the clock
    has run into the next minute on its own, and R4129, R4130 and R4135, read in one request (one scan), must show
    that new minute, R4135 = hour × 256 + minute."""
    wrong = []
    for when, word in R4135_RUNNING:
        assert rtc.set(at(when)).accepted, f"{when}: refused (M1955 = 1)"
        bench.wait(1.0)  # the chip restarted its second at the set: it has ticked into the next minute by now
        _second, minute, hour, *_, hour_minute = io.read_words("R4128", 8)
        if (hour, minute) != (word >> 8, word & 0xFF):
            wrong.append(f"{when} + 1 s: R4130:R4129 = {hour}:{minute}, not yet the next minute")
        elif hour_minute != word:
            wrong.append(f"{when} + 1 s: R4135 = {hour_minute:04X}H, expected {word:04X}H for {hour}:{minute}")
    assert not wrong, "\n".join(wrong)


@pytest.mark.spec("RTC-SET-1", "RTC-SET-2")
def test_set_takes_a_one_scan_pulse_of_m1952(bench, rtc, io):
    """The set happens at M1952's fall however briefly M1952 was 1: M1952 := 1 with R4128–R4134 in one request and
    M1952 := 0 in the very next.  The clock is first set to a time far from the pulsed one, so only the pulse's set
    can make it show that.  On a port that services each request at the end of a scan (port 0's rule) the PLC has
    seen the 1 for a scan; on a port that may answer mid-scan both writes may land in one scan, and a clock that
    did not take the pulse is no verdict there."""
    assert rtc.set(at("2024-03-05 10:00:00")).accepted
    pulsed = at("2031-08-14 17:30:20")
    began = bench.time.now()
    try:
        result = rtc.set(pulsed, pulse=True)
        second, *rest = result.shown.to_registers()  # read with M1955 from a scan after the fall
        most = 20 + int(bench.time.now() - began) + 1
        taken = result.accepted and rest == [30, 17, 14, 8, 31, 4] and 20 <= second <= most
        shown = f"M1955 = {int(result.refused)}, R4128–R4134 = {[second, *rest]}"
    except RtcSetLost as lost:  # M1955 = 0, the clock not on the time pulsed
        taken, shown = False, str(lost)
    if not taken and bench.plc.scan_counter is not None and not bench.plc.answers_at_scan_end:
        pytest.fail(f"inconclusive: a one-scan pulse of M1952 did not set the clock ({shown}), but this wire may "
                    f"answer mid-scan ([bench] answers_at_scan_end is not set), so no scan may have seen the 1",
                    pytrace=False)
    assert taken, f"a one-scan pulse of M1952 (1, then 0 in the next request) did not set {pulsed}: {shown}"


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
    # written while M1952 = 1: they must stay put across a tick of the chip (a PLC still copying the chip out,
    # every scan or at each new second, overwrites them within this second)
    io.write_words("R4128", [30, 20, 10, 4, 7, 30, 4])  # 2030-07-04 10:20:30, a Thursday
    bench.wait(1.2)
    assert io.read_words("R4128", 7) == [30, 20, 10, 4, 7, 30, 4], "R4128–R4134 changed while M1952 = 1"

    began = bench.time.now()
    io.write("M1952", 0)  # falling edge: the PLC sets the clock from R4128–R4134
    bench.settle()
    bench.wait(1.0)  # read-out resumes: the registers follow the chip's next tick
    second, *rest = io.read_words("R4128", 7)
    assert rest == [20, 10, 4, 7, 30, 4]
    most = 30 + int(bench.time.now() - began)
    assert 31 <= second <= most, f"second {second}: read-out did not resume from the time that was set"


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


@pytest.fixture
def no_chip(bench):
    """A bench whose profile says its PLC has no RTC chip ([rtc] chip = "none"); else skip with the reason."""
    if bench.profile.rtc is None or bench.profile.rtc.chip != 0:
        pytest.skip('the bench profile does not say this PLC has no RTC chip ([rtc] chip = "none")')
    return bench


@pytest.mark.spec("RTC-FLAG-1", "RTC-FLAG-2", "RTC-CHIP-1")
def test_without_a_chip_d4053_is_0_m1954_is_0_and_r4128_r4135_are_not_updated(no_chip, io):
    """D4053 = 0: no RTC chip.  M1954 = 0, and no scan copies a clock into R4128–R4135: what is there stays
    there, ticking nowhere, and what a program writes into R4128–R4134 while M1952 = 0 is not overwritten."""
    bench = no_chip
    if bench.unreachable_reason("D4053") is None:
        assert io.read("D4053") == 0, "D4053 names a chip; the bench profile says there is none"
    assert io.read("M1954") == 0, "M1954 = 1 (RTC fitted) on a PLC without an RTC chip"
    before = io.read_words("R4128", 8)
    writable = bench.cannot_reach("R4128-R4134") is None
    written = [30, 20, 10, 4, 7, 30, 4]  # 2030-07-04 10:20:30: a time a running clock would move on from
    if writable:
        io.write_words("R4128", written)
    bench.wait(1.2)  # a clock would have ticked (and a read-out overwritten the written values) within this
    after = io.read_words("R4128", 8)
    assert after[7] == before[7], f"R4135 changed from {before[7]:04X}H to {after[7]:04X}H without a chip"
    assert after[:7] == (written if writable else before[:7]), (
        f"R4128–R4134 = {after[:7]} after 1.2 s, were {written if writable else before[:7]}: updated without a chip")
