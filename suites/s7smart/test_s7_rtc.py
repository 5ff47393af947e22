"""S7-200 SMART READ_RTC / SET_RTC / SET_RTC_I (system manual, clock instructions; spec/s7-200smart-rtc.md).

T = year, month, day, hour, minute, second, reserved 00, weekday — all BCD; weekday 1 = Sunday … 7 = Saturday,
ignored by SET_RTC and computed from the date by READ_RTC.  An invalid T: ENO = 0, error 0007H, clock unchanged.
Expectations are written as the bytes a status chart would show.
"""

from __future__ import annotations

import calendar
import datetime as dt

import pytest

pytestmark = pytest.mark.family("s7-200smart")

T_DATA_ERROR = 0x0007


def T(text: str) -> bytes:
    """A time buffer written as a status chart shows it: ``T("24 06 15 08 30 00 00 07")``."""
    data = bytes.fromhex(text)
    assert len(data) == 8, text
    return data


SATURDAY_15_JUNE_2024 = T("24 06 15 08 30 00 00 07")


def bcd(n: int) -> int:
    return n // 10 << 4 | n % 10


def day_of_week(date: dt.date) -> int:
    """The manual's day of week (1 = Sunday … 7 = Saturday) from Python's calendar, independent of the PLC."""
    return date.isoweekday() % 7 + 1


def buffer_of(when: dt.datetime) -> bytes:
    """The time buffer of ``when`` as a status chart shows it, weekday computed."""
    fields = (when.year - 2000, when.month, when.day, when.hour, when.minute, when.second, 0)
    return bytes(bcd(v) for v in fields) + bytes([day_of_week(when.date())])


def seconds_window(seconds: range, since: tuple | None, set_second: int = 0) -> range:
    """``seconds`` (the manual's window), its top raised where ``since`` = (bench, bench time just before a set of
    second ``set_second``) shows more bench time gone by: that second plus the whole seconds since the moment,
    measured after the read — however long the requests took on this bench.  The bottom stays."""
    if since is None:
        return seconds
    bench, began = since
    return range(seconds.start, max(seconds.stop, set_second + int(bench.time.now() - began) + 2))


def assert_reads(clock, expected_prefix: bytes, weekday: int, seconds: range, what: str = "", *,
                 since: tuple | None = None, set_second: int = 0) -> None:
    """READ_RTC succeeded and shows year…minute = ``expected_prefix``, a second in ``seconds``, 00, ``weekday``
    (``since``, ``set_second``: :func:`seconds_window`)."""
    result = clock.read()
    assert result.accepted, f"{what}READ_RTC failed: {result}"
    seconds = seconds_window(seconds, since, set_second)
    got = result.buffer
    assert got[:5] == expected_prefix, f"{what}clock reads {got.hex(' ').upper()}"
    assert got[5] in [bcd(s) for s in seconds], f"{what}second is {got[5]:02X} (expected {list(seconds)})"
    assert got[6:] == bytes([0x00, weekday]), f"{what}reserved/weekday read {got[6]:02X} {got[7]:02X}"


# -- set and read ----------------------------------------------------------------------------------------------
@pytest.mark.spec("S7-RTC-1", "S7-RTC-2", "S7-RTC-3", "S7-RTC-7", "S7-RTC-9")
@pytest.mark.parametrize("buffer, weekday", [
    (T("24 06 15 08 30 00 00 07"), 7),   # Saturday
    (T("00 01 01 00 00 00 00 07"), 7),   # the first second of the clock's range, a Saturday
    (T("99 12 31 23 59 30 00 05"), 5),   # the last day of 2099, a Thursday
    (T("12 03 04 17 45 10 00 01"), 1),   # 16#12 = 2012 (the manual's example), a Sunday
])
def test_set_then_read_round_trip(bench, clock, buffer, weekday):
    began = bench.time.now()
    result = clock.set(buffer)
    assert result.accepted, f"SET_RTC refused a valid buffer: {result}"
    second = int(f"{buffer[5]:02X}")
    assert_reads(clock, buffer[:5], weekday, range(second, second + 3), since=(bench, began), set_second=second)


@pytest.mark.spec("S7-RTC-9")
def test_clock_runs_after_a_set(bench, clock):
    began = bench.time.now()
    assert clock.set(T("24 06 15 08 30 00 00 07")).accepted
    bench.wait(5)
    assert_reads(clock, T("24 06 15 08 30 00 00 00")[:5], 7, range(5, 8), since=(bench, began))


# -- weekday -----------------------------------------------------------------------------------------------------
@pytest.mark.spec("S7-RTC-7")
@pytest.mark.parametrize("written", [0x01, 0x03, 0x06])
def test_weekday_ignored_on_write_and_computed_on_read(bench, clock, written):
    began = bench.time.now()
    result = clock.set(bytes([0x24, 0x06, 0x15, 0x08, 0x30, 0x00, 0x00, written]))
    assert result.accepted, f"SET_RTC refused a valid date with weekday {written:02X}: {result}"
    assert_reads(clock, SATURDAY_15_JUNE_2024[:5], 7, range(0, 3), f"weekday {written:02X} written: ",
                 since=(bench, began))


@pytest.mark.spec("S7-RTC-9", "S7-RTC-7")
def test_weekday_advances_at_midnight(bench, clock):
    began = bench.time.now()
    assert clock.set(T("24 06 15 23 59 58 00 07")).accepted  # Saturday 23:59:58
    bench.wait(3)
    # Sunday; the set's second counted from the minute read: 58 is 2 s before it
    assert_reads(clock, T("24 06 16 00 00 00 00 00")[:5], 1, range(1, 4), since=(bench, began), set_second=-2)


# -- refused buffers: ENO = 0, 0007H, clock unchanged ---------------------------------------------------------
#: dates that do not exist — "an invalid date (e.g. 30 February) is not accepted: ENO = 0, 0007H" (the manual):
#: every 30-day month's 31st, 30 February, 29 February of a common year, month and day one past each end
INVALID_DATES = {
    "30 February 2024": T("24 02 30 09 00 00 00 06"),
    "29 February 2023": T("23 02 29 09 00 00 00 04"),
    "31 April": T("24 04 31 09 00 00 00 04"),
    "31 June": T("24 06 31 09 00 00 00 02"),
    "31 September": T("24 09 31 09 00 00 00 03"),
    "31 November": T("24 11 31 09 00 00 00 07"),
    "month 13": T("24 13 01 09 00 00 00 04"),
    "month 00": T("24 00 01 09 00 00 00 04"),
    "day 00": T("24 06 00 09 00 00 00 04"),
    "day 32": T("24 01 32 09 00 00 00 04"),
}
#: the time one past its end in each byte, and a non-zero reserved byte: "illegal data is not written" (the
#: manual); that it ends with 0007H is the spec's reading
OUT_OF_RANGE = {
    "hour 24": T("24 06 20 24 00 00 00 05"),
    "minute 60": T("24 06 20 09 60 00 00 05"),
    "second 60": T("24 06 20 09 00 60 00 05"),
    "reserved byte 01": T("24 06 20 09 00 00 01 05"),
    "reserved byte 80": T("24 06 20 09 00 00 80 05"),
    "reserved byte 0A": T("24 06 20 09 00 00 0A 05"),
}
#: a non-BCD nibble (A–F) in each nibble of each date and time byte of a valid buffer (20 June 2024 09:00:00)
VALID_BASE = T("24 06 20 09 00 00 00 05")
NON_BCD = {
    f"non-BCD {field} 16#{value:02X}": VALID_BASE[:i] + bytes([value]) + VALID_BASE[i + 1:]
    for i, field in enumerate(("year", "month", "day", "hour", "minute", "second"))
    for value in [(nibble << 4) | (VALID_BASE[i] & 0x0F) for nibble in range(0xA, 0x10)]
    + [(VALID_BASE[i] & 0xF0) | nibble for nibble in range(0xA, 0x10)]
}


def _decode(buffer: bytes) -> dt.datetime | None:
    """The date and time in a BCD buffer READ_RTC left; None when it holds no legal date and time."""
    if any(b >> 4 > 9 or b & 0xF > 9 for b in buffer[:6]):
        return None
    y, mo, d, h, mi, s = (int(f"{b:02X}") for b in buffer[:6])
    try:
        return dt.datetime(2000 + y, mo, d, h, mi, s)
    except ValueError:
        return None


def _refuse_each(bench, clock, cases: dict[str, bytes], *, error_code: bool) -> None:
    """The clock set to SATURDAY_15_JUNE_2024, then every buffer of ``cases`` back to back: the clock must not be
    changed by any (READ_RTC right after each shows 15 June 2024 08:30, run on by the time since the set); with
    ``error_code`` each must also end with ENO = 0 and 0007H.  One wait at the end: the clock runs on."""
    began = bench.time.now()
    assert clock.set(SATURDAY_15_JUNE_2024).accepted
    start = _decode(SATURDAY_15_JUNE_2024)
    assert start is not None, "SATURDAY_15_JUNE_2024 is not a date: the suite's constant is wrong"
    wrong = []
    for case, buffer in cases.items():
        result = clock.set(buffer)
        if error_code and (result.eno, result.error) != (0, T_DATA_ERROR):
            wrong.append(f"{case}: SET_RTC ended with ENO = {result.eno}, error {result.error:04X}H")
        read = clock.read().buffer
        ran = bench.time.now() - began
        shown = _decode(read)
        if shown is None or not start <= shown <= start + dt.timedelta(seconds=ran + 1) or read[7] != 7:
            wrong.append(f"{case}: the clock was changed: READ_RTC = {read.hex(' ').upper()}")
    assert not wrong, "\n".join(wrong)
    bench.wait(2)
    shown = _decode(clock.read().buffer)
    assert shown is not None and (
        start + dt.timedelta(seconds=2) <= shown <= start + dt.timedelta(seconds=bench.time.now() - began + 1)), (
        f"the clock did not run on after the refusals: {shown}")


@pytest.mark.spec("S7-RTC-4", "S7-RTC-8", "S7-RTC-3")
def test_invalid_dates_refused_with_0007_and_the_clock_unchanged(bench, clock):
    _refuse_each(bench, clock, INVALID_DATES, error_code=True)


@pytest.mark.spec("S7-RTC-5", "S7-RTC-3", "S7-RTC-1")
def test_illegal_bytes_are_not_written(bench, clock):
    """The time one past its end, a non-BCD nibble in every nibble of every date and time byte, a non-zero
    reserved byte: the manual says illegal data is not written."""
    _refuse_each(bench, clock, {**OUT_OF_RANGE, **NON_BCD}, error_code=False)


@pytest.mark.spec("S7-RTC-6", "S7-RTC-5")
def test_illegal_bytes_end_with_eno_0_and_0007(bench, clock):
    _refuse_each(bench, clock, {**OUT_OF_RANGE, **NON_BCD}, error_code=True)


# -- the running clock ---------------------------------------------------------------------------------------------
#: the last second of a day → READ_RTC one second later: every month's end of a leap year, the 30th of every
#: 31-day month, 28 February in a leap year, a common year and 2000, 29 February 2000, the end of a year; the
#: weekday (1 = Sunday) advancing through every day of the week
MIDNIGHTS = [
    (T("24 01 30 23 59 59 00 03"), T("24 01 31 00 00 00 00 04")),
    (T("24 01 31 23 59 59 00 04"), T("24 02 01 00 00 00 00 05")),
    (T("24 02 28 23 59 59 00 04"), T("24 02 29 00 00 00 00 05")),
    (T("24 02 29 23 59 59 00 05"), T("24 03 01 00 00 00 00 06")),
    (T("23 02 28 23 59 59 00 03"), T("23 03 01 00 00 00 00 04")),
    (T("00 02 28 23 59 59 00 02"), T("00 02 29 00 00 00 00 03")),
    (T("00 02 29 23 59 59 00 03"), T("00 03 01 00 00 00 00 04")),
    (T("24 03 30 23 59 59 00 07"), T("24 03 31 00 00 00 00 01")),
    (T("24 03 31 23 59 59 00 01"), T("24 04 01 00 00 00 00 02")),
    (T("24 04 30 23 59 59 00 03"), T("24 05 01 00 00 00 00 04")),
    (T("24 05 30 23 59 59 00 05"), T("24 05 31 00 00 00 00 06")),
    (T("24 05 31 23 59 59 00 06"), T("24 06 01 00 00 00 00 07")),
    (T("24 06 30 23 59 59 00 01"), T("24 07 01 00 00 00 00 02")),
    (T("24 07 30 23 59 59 00 03"), T("24 07 31 00 00 00 00 04")),
    (T("24 07 31 23 59 59 00 04"), T("24 08 01 00 00 00 00 05")),
    (T("24 08 30 23 59 59 00 06"), T("24 08 31 00 00 00 00 07")),
    (T("24 08 31 23 59 59 00 07"), T("24 09 01 00 00 00 00 01")),
    (T("24 09 30 23 59 59 00 02"), T("24 10 01 00 00 00 00 03")),
    (T("24 10 30 23 59 59 00 04"), T("24 10 31 00 00 00 00 05")),
    (T("24 10 31 23 59 59 00 05"), T("24 11 01 00 00 00 00 06")),
    (T("24 11 30 23 59 59 00 07"), T("24 12 01 00 00 00 00 01")),
    (T("24 12 30 23 59 59 00 02"), T("24 12 31 00 00 00 00 03")),
    (T("24 12 31 23 59 59 00 03"), T("25 01 01 00 00 00 00 04")),
]


@pytest.mark.spec("S7-RTC-9", "S7-RTC-8", "S7-RTC-7")
def test_clock_runs_over_every_month_end_and_leap_day(bench, clock):
    """One bench second per case: one second after SET_RTC the clock must have ticked into the next day, and not
    further than the time since the set."""
    wrong = []
    for buffer, after in MIDNIGHTS:
        began = bench.time.now()
        result = clock.set(buffer)
        if not result.accepted:
            wrong.append(f"{buffer.hex(' ').upper()}: SET_RTC refused it ({result})")
            continue
        bench.wait(1.0)
        read = clock.read().buffer
        most = int(bench.time.now() - began) - 1
        if read[:5] != after[:5] or read[6:] != after[6:] or read[5] not in [bcd(s) for s in range(max(most, 0) + 1)]:
            wrong.append(f"{buffer.hex(' ').upper()} + 1 s: READ_RTC = {read.hex(' ').upper()}, expected "
                         f"{after.hex(' ').upper()}")
    assert not wrong, "\n".join(wrong)


def _last_seconds_of_days() -> list[dt.datetime]:
    """23:59:59 of every month's last day in 2023 (a common year), of the 30th of each of its 31-day months, of
    28 and 29 February 2096 (a leap year by the 4-year rule) and of 28 February 2000 (leap by the 400-year rule):
    dates from Python's calendar, where the table above is written out for 2024 (and February 2023 and 2000)."""
    days = [dt.date(2023, m, calendar.monthrange(2023, m)[1]) for m in range(1, 13)]
    days += [dt.date(2023, m, 30) for m in range(1, 13) if calendar.monthrange(2023, m)[1] == 31]
    days += [dt.date(2096, 2, 28), dt.date(2096, 2, 29), dt.date(2000, 2, 28)]
    return [dt.datetime.combine(day, dt.time(23, 59, 59)) for day in days]


def _read_when_the_day_changes(bench, clock, day: int, began: float) -> bytes | None:
    """READ_RTC, polled until its day byte differs from ``day`` (the tick the set leads to: fresh evidence, not a
    fixed wait); None when it has not changed 3 s after ``began``, much longer than the one second it needs."""
    while True:
        read = clock.read().buffer
        if read[2] != day:
            return read
        if bench.time.now() - began > 3.0:
            return None
        bench.wait(0.2)


@pytest.mark.spec("S7-RTC-9", "S7-RTC-8", "S7-RTC-7")
def test_clock_ticks_into_the_next_day_as_the_calendar_does(bench, clock):
    """The month-end rule seen from another side than the table above: other years, and each case read as soon as
    the day byte changes.  What READ_RTC shows then must be the set time plus the seconds that have passed, by
    Python's calendar — the next day (the 31st, 29 February or the 1st of the next month), 00:00:0x, its weekday."""
    wrong = []
    for start in _last_seconds_of_days():
        began = bench.time.now()
        result = clock.set(buffer_of(start))
        if not result.accepted:
            wrong.append(f"{start}: SET_RTC refused it ({result})")
            continue
        read = _read_when_the_day_changes(bench, clock, bcd(start.day), began)
        ran = bench.time.now() - began
        shown = _decode(read) if read is not None else None
        if (shown is None or not start + dt.timedelta(seconds=1) <= shown <= start + dt.timedelta(seconds=ran + 1)
                or read[6:] != bytes([0x00, day_of_week(shown.date())])):
            wrong.append(f"{start} + {ran:.1f} s: READ_RTC = {read.hex(' ').upper() if read else 'the same day'}, "
                         f"expected {buffer_of(start + dt.timedelta(seconds=1)).hex(' ').upper()} (± seconds)")
    assert not wrong, "\n".join(wrong)


@pytest.mark.spec("S7-RTC-17", "S7-RTC-7")
def test_clock_runs_from_2099_into_2000(bench, clock):
    """The clock keeps two-digit years: the second after 2099-12-31 23:59:59 (a Thursday) is 2000-01-01 00:00:00,
    a Saturday — not a year 2100 (16#A0, or 00 with 2100's Friday), and the clock does not stop."""
    began = bench.time.now()
    assert clock.set(T("99 12 31 23 59 58 00 05")).accepted
    bench.wait(3)  # two ticks past the set: the read comes after the year's wrap
    assert_reads(clock, T("00 01 01 00 00 00 00 00")[:5], 7, range(1, 4), "2099-12-31 23:59:58 + 3 s: ",
                 since=(bench, began), set_second=-2)


@pytest.mark.spec("S7-RTC-4")
def test_valid_set_after_a_refused_one(bench, clock):
    assert clock.set(INVALID_DATES["30 February 2024"]).error == T_DATA_ERROR
    began = bench.time.now()
    result = clock.set(T("24 02 29 09 00 00 00 01"))
    assert result.accepted, f"valid set after a refused one: {result}"
    assert_reads(clock, T("24 02 29 09 00 00 00 00")[:5], 5, range(0, 3),  # 29 Feb 2024 was a Thursday
                 since=(bench, began))


# -- leap years 2000–2099 ------------------------------------------------------------------------------------------
@pytest.mark.spec("S7-RTC-8", "S7-RTC-7")
def test_leap_days_2000_to_2096_accepted_with_correct_weekday(clock):
    refused, wrong = [], []
    for year in range(2000, 2100, 4):
        buffer = bytes([bcd(year - 2000), 0x02, 0x29, 0x12, 0x00, 0x00, 0x00, 0x01])
        result = clock.set(buffer)
        if not result.accepted:
            refused.append(f"{year}: {result}")
            continue
        expected = day_of_week(dt.date(year, 2, 29))
        got = clock.read().buffer
        if got[:5] != buffer[:5] or got[7] != expected:
            wrong.append(f"{year}: read {got.hex(' ').upper()}, weekday expected {expected}")
    assert not refused, f"29 February refused in leap years: {refused}"
    assert not wrong, f"29 February read back wrong: {wrong}"


@pytest.mark.spec("S7-RTC-8", "S7-RTC-4")
@pytest.mark.parametrize("year", [2001, 2023, 2025, 2099])
def test_29_february_refused_in_common_years(clock, year):
    result = clock.set(bytes([bcd(year - 2000), 0x02, 0x29, 0x12, 0x00, 0x00, 0x00, 0x01]))
    assert (result.eno, result.error) == (0, T_DATA_ERROR), f"29 Feb {year}: {result}"


# -- SET_RTC_I: the same eight bytes as plain integers ------------------------------------------------------------
@pytest.fixture
def set_i(clock):
    if not clock.has_set_i:
        pytest.skip("the bench's clock program has no SET_RTC_I ([s7rtc] set_i_trigger)")
    return clock


@pytest.mark.spec("S7-RTC-15")
@pytest.mark.parametrize("integers, bcd_buffer, weekday", [
    ([24, 6, 15, 8, 30, 0, 0, 0], T("24 06 15 08 30 00 00 00"), 7),
    ([36, 2, 29, 23, 59, 0, 0, 1], T("36 02 29 23 59 00 00 00"), 6),   # 29 Feb 2036, a Friday
    ([0, 1, 1, 0, 0, 0, 0, 0], T("00 01 01 00 00 00 00 00"), 7),
])
def test_set_rtc_i_equals_set_rtc_with_bcd(bench, set_i, integers, bcd_buffer, weekday):
    began = bench.time.now()
    result = set_i.set_int(integers)
    assert result.accepted, f"SET_RTC_I refused {integers}: {result}"
    assert_reads(set_i, bcd_buffer[:5], weekday, range(0, 3), "SET_RTC_I: ", since=(bench, began))
    began = bench.time.now()
    assert set_i.set(bcd_buffer).accepted
    assert_reads(set_i, bcd_buffer[:5], weekday, range(0, 3), "SET_RTC: ", since=(bench, began))


@pytest.mark.spec("S7-RTC-15", "S7-RTC-4")
@pytest.mark.parametrize("integers", [[24, 2, 30, 9, 0, 0, 0, 0], [23, 2, 29, 9, 0, 0, 0, 0],
                                      [24, 13, 1, 9, 0, 0, 0, 0],
                                      pytest.param([24, 6, 20, 24, 0, 0, 0, 0], marks=pytest.mark.spec("S7-RTC-6")),
                                      pytest.param([24, 6, 20, 9, 0, 0, 1, 0], marks=pytest.mark.spec("S7-RTC-6")),
                                      [24, 6, 20, 9, 100, 0, 0, 0]])  # (minute 100: no two-digit number at all)
def test_set_rtc_i_refuses_what_set_rtc_refuses(bench, set_i, integers):
    began = bench.time.now()
    assert set_i.set(SATURDAY_15_JUNE_2024).accepted
    result = set_i.set_int(integers)
    assert (result.eno, result.error) == (0, T_DATA_ERROR), f"SET_RTC_I {integers}: {result}"
    assert_reads(set_i, SATURDAY_15_JUNE_2024[:5], 7, range(0, 3), since=(bench, began))


# -- edge-triggered --------------------------------------------------------------------------------------------
@pytest.mark.spec("S7-RTC-10")
def test_held_trigger_sets_once(bench, clock):
    """SET_RTC must run on a one-shot edge: holding the trigger does not keep setting the clock."""
    began = bench.time.now()
    assert clock.set(T("24 06 15 08 30 00 00 07"), hold=True).accepted
    bench.wait(3)
    clock.write_set_buffer(T("24 01 01 01 01 01 00 02"))  # a new time while the trigger is still held
    bench.wait(2)
    assert_reads(clock, T("24 06 15 08 30 00 00 00")[:5], 7, range(5, 8), "trigger held 5 s: ",
                 since=(bench, began))
    clock.release()
    began = bench.time.now()
    assert clock.set(T("24 01 01 01 01 01 00 02")).accepted  # a fresh edge takes the new buffer
    assert_reads(clock, T("24 01 01 01 01 00 00 00")[:5], 2, range(1, 4),  # 1 Jan 2024 was a Monday
                 since=(bench, began), set_second=1)


@pytest.mark.spec("S7-RTC-10")
def test_clock_runs_under_a_held_trigger_and_each_new_edge_sets_it(bench, clock):
    """The one-shot rule from another side than the test above: the buffer never changes.  Run on the trigger's
    level, SET_RTC would load the same time again at every scan and the clock would stand still while it is held;
    run on its fall too, it would load it again at the release.  Each new rising edge does set it."""
    began = bench.time.now()
    assert clock.set(SATURDAY_15_JUNE_2024, hold=True).accepted
    bench.wait(2)
    assert_reads(clock, SATURDAY_15_JUNE_2024[:5], 7, range(2, 5), "trigger held 2 s: ", since=(bench, began))
    clock.release()
    bench.wait(2)
    assert_reads(clock, SATURDAY_15_JUNE_2024[:5], 7, range(4, 7), "released, 2 s later: ", since=(bench, began))
    before = clock.read()  # the running clock just before the second edge (about :04–:06)
    assert before.accepted, f"READ_RTC failed: {before}"
    began = bench.time.now()
    assert clock.set(SATURDAY_15_JUNE_2024).accepted
    assert_reads(clock, SATURDAY_15_JUNE_2024[:5], 7, range(0, 3), "a second edge: ", since=(bench, began))
    # fresh evidence that the edge set it, however long the set took: a clock that ignored the edge would now read
    # at least its earlier second plus the whole seconds since (less one for the phase); a set one restarted at :00
    ran_on = int(f"{before.buffer[5]:02X}") + int(bench.time.now() - began) - 1
    now = int(f"{clock.read().buffer[5]:02X}")
    assert now < ran_on, (f"a second edge: the clock reads :{now:02d}, what it would read had the edge been ignored "
                          f"(:{before.buffer[5]:02X} before it, {bench.time.now() - began:.1f} s since)")


# -- power loss (emulator: power cycles on demand) -----------------------------------------------------------------
@pytest.mark.needs("power_cycle", reason="switches the CPU off and on")
@pytest.mark.spec("S7-RTC-13")
def test_power_loss_starts_at_2000_01_01_saturday(bench, clock):
    assert clock.set(T("24 06 15 08 30 00 00 07")).accepted
    began = bench.time.now()
    bench.power_cycle(backup_expired=True)
    assert_reads(clock, T("00 01 01 00 00 00 00 00")[:5], 7, range(0, 2), "after the back-up ran out: ",
                 since=(bench, began))


@pytest.mark.needs("power_cycle", reason="switches the CPU off and on")
@pytest.mark.spec("S7-RTC-14")
def test_power_cycle_keeps_the_time_only_with_an_rtc(bench, clock):
    set_at = bench.time.now()
    assert clock.set(T("24 06 15 08 30 00 00 07")).accepted
    bench.wait(2)
    cycled_at = bench.time.now()
    bench.power_cycle(backup_expired=False)
    if bench.settings.cpu in ("CR40", "CR60"):  # no RTC: the set value is lost at the next power cycle
        assert_reads(clock, T("00 01 01 00 00 00 00 00")[:5], 7, range(0, 2), f"{bench.settings.cpu}: ",
                     since=(bench, cycled_at))
    else:
        assert_reads(clock, T("24 06 15 08 30 00 00 00")[:5], 7, range(2, 5), f"{bench.settings.cpu}: ",
                     since=(bench, set_at))


@pytest.mark.needs("power_on_state", reason="only a CPU straight from power-on shows where its clock started")
@pytest.mark.spec("S7-RTC-14", "S7-RTC-13")
def test_a_cpu_without_a_clock_starts_at_2000_01_01(bench, clock):
    """CR40 and CR60 have no RTC: powered on, the clock starts at 2000-01-01 00:00:00 (as after a power loss) and
    runs on from there — read now (less than a day after power-on), it shows 1 January 2000."""
    if bench.settings.cpu not in ("CR40", "CR60"):
        pytest.skip(f"a {bench.settings.cpu} has a real-time clock: it starts where it was last set")
    result = clock.read()
    assert result.eno == 1, f"READ_RTC: {result}"
    assert result.buffer[:3] == bytes([0x00, 0x01, 0x01]), (
        f"{bench.settings.cpu} (no RTC) straight from power-on: READ_RTC reads {result.buffer.hex(' ')}, expected "
        f"00 01 01 … (2000-01-01, the clock counting from power-on)")


# -- the CPU's own clock functions (S7 protocol: read/set the time of day) -----------------------------------------
@pytest.fixture
def cpu_clock(clock):
    if clock.cpu_clock() is None:
        pytest.skip("this wire has no clock functions: the S7 protocol has them (target s7+tcp://HOST:102)")
    return clock


@pytest.mark.spec("S7-WIRE-2")
def test_cpu_clock_function_reads_the_clock_read_rtc_reads(bench, cpu_clock):
    began = bench.time.now()
    assert cpu_clock.set(SATURDAY_15_JUNE_2024).accepted
    via_protocol = cpu_clock.cpu_clock()
    assert (via_protocol.year, via_protocol.month, via_protocol.day, via_protocol.hour, via_protocol.minute) == \
        (2024, 6, 15, 8, 30), f"the CPU clock function reads {via_protocol} after SET_RTC of 2024-06-15 08:30:00"
    assert via_protocol.second in seconds_window(range(0, 3), (bench, began)), (
        f"the CPU clock function reads {via_protocol}")
    assert_reads(cpu_clock, SATURDAY_15_JUNE_2024[:5], 7, range(0, 3), "after reading it with the clock function: ",
                 since=(bench, began))


@pytest.mark.spec("S7-WIRE-2")
def test_cpu_clock_function_sets_what_read_rtc_reads(bench, cpu_clock):
    began = bench.time.now()
    cpu_clock.set_cpu_clock(dt.datetime(2012, 3, 4, 17, 45, 10))
    assert_reads(cpu_clock, T("12 03 04 17 45 10 00 01")[:5], 1, range(10, 13), "set with the clock function: ",
                 since=(bench, began), set_second=10)
