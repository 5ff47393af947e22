"""S7-200 SMART READ_RTC / SET_RTC / SET_RTC_I (system manual, clock instructions; spec/s7-200smart-rtc.md).

T = year, month, day, hour, minute, second, reserved 00, weekday — all BCD; weekday 1 = Sunday … 7 = Saturday,
ignored by SET_RTC and computed from the date by READ_RTC.  An invalid T: ENO = 0, error 0007H, clock unchanged.
Expectations are written as the bytes a status chart would show.
"""

from __future__ import annotations

import datetime as dt

import pytest

pytestmark = pytest.mark.family("s7-200smart")

T_DATA_ERROR = 0x0007


def T(text: str) -> bytes:  # noqa: N802 - the manual's name for the buffer
    """A time buffer written as a status chart shows it: ``T("24 06 15 08 30 00 00 07")``."""
    data = bytes.fromhex(text)
    assert len(data) == 8, text
    return data


SATURDAY_15_JUNE_2024 = T("24 06 15 08 30 00 00 07")


def bcd(n: int) -> int:
    return n // 10 << 4 | n % 10


def assert_reads(clock, expected_prefix: bytes, weekday: int, seconds: range, what: str = "") -> None:
    """READ_RTC succeeded and shows year…minute = ``expected_prefix``, a second in ``seconds``, 00, ``weekday``."""
    result = clock.read()
    assert result.accepted, f"{what}READ_RTC failed: {result}"
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
def test_set_then_read_round_trip(clock, buffer, weekday):
    result = clock.set(buffer)
    assert result.accepted, f"SET_RTC refused a valid buffer: {result}"
    second = int(f"{buffer[5]:02X}")
    assert_reads(clock, buffer[:5], weekday, range(second, second + 3))


@pytest.mark.spec("S7-RTC-9")
def test_clock_runs_after_a_set(bench, clock):
    assert clock.set(T("24 06 15 08 30 00 00 07")).accepted
    bench.wait(5)
    assert_reads(clock, T("24 06 15 08 30 00 00 00")[:5], 7, range(5, 8))


# -- weekday -----------------------------------------------------------------------------------------------------
@pytest.mark.spec("S7-RTC-7")
@pytest.mark.parametrize("written", [0x01, 0x03, 0x06])
def test_weekday_ignored_on_write_and_computed_on_read(clock, written):
    result = clock.set(bytes([0x24, 0x06, 0x15, 0x08, 0x30, 0x00, 0x00, written]))
    assert result.accepted, f"SET_RTC refused a valid date with weekday {written:02X}: {result}"
    assert_reads(clock, SATURDAY_15_JUNE_2024[:5], 7, range(0, 3), f"weekday {written:02X} written: ")


@pytest.mark.spec("S7-RTC-9", "S7-RTC-7")
def test_weekday_advances_at_midnight(bench, clock):
    assert clock.set(T("24 06 15 23 59 58 00 07")).accepted  # Saturday 23:59:58
    bench.wait(3)
    assert_reads(clock, T("24 06 16 00 00 00 00 00")[:5], 1, range(1, 4))  # Sunday


# -- refused buffers: ENO = 0, 0007H, clock unchanged ---------------------------------------------------------
INVALID = {
    "30 February 2024": T("24 02 30 09 00 00 00 06"),
    "29 February 2023": T("23 02 29 09 00 00 00 04"),
    "31 April": T("24 04 31 09 00 00 00 04"),
    "month 13": T("24 13 01 09 00 00 00 04"),
    "month 00": T("24 00 01 09 00 00 00 04"),
    "day 00": T("24 06 00 09 00 00 00 04"),
    "hour 24": T("24 06 20 24 00 00 00 05"),
    "minute 60": T("24 06 20 09 60 00 00 05"),
    "second 60": T("24 06 20 09 00 60 00 05"),
    "non-BCD minute 16#1A": T("24 06 20 09 1A 00 00 05"),
    "non-BCD year 16#A4": T("A4 06 20 09 00 00 00 05"),
    "non-BCD day 16#0F": T("24 06 0F 09 00 00 00 05"),
    "reserved byte 01": T("24 06 20 09 00 00 01 05"),
    "reserved byte 80": T("24 06 20 09 00 00 80 05"),
}


#: what each case checks beyond S7-RTC-4 (ENO = 0, 0007H, the clock unchanged); S7-RTC-6 is the spec's reading
#: (needs spec_choices)
CHECKS = {"29 February 2023": ("S7-RTC-8",), "hour 24": ("S7-RTC-3", "S7-RTC-6"),
          "minute 60": ("S7-RTC-3", "S7-RTC-6"), "second 60": ("S7-RTC-3", "S7-RTC-6"),
          "non-BCD minute 16#1A": ("S7-RTC-5", "S7-RTC-6"),
          "non-BCD year 16#A4": ("S7-RTC-5", "S7-RTC-6"), "non-BCD day 16#0F": ("S7-RTC-5", "S7-RTC-6"),
          "reserved byte 01": ("S7-RTC-3", "S7-RTC-5", "S7-RTC-6"),
          "reserved byte 80": ("S7-RTC-3", "S7-RTC-5", "S7-RTC-6")}


@pytest.mark.spec("S7-RTC-4")
@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.spec(*CHECKS.get(c, ("S7-RTC-3",))), id=c)
                                  for c in INVALID])
def test_invalid_buffer_refused_with_0007(bench, clock, case):
    assert clock.set(SATURDAY_15_JUNE_2024).accepted
    result = clock.set(INVALID[case])
    assert result.eno == 0, f"{case}: SET_RTC ended with ENO = 1 ({result})"
    assert result.error == T_DATA_ERROR, f"{case}: error {result.error:04X}H, expected 0007H"
    bench.wait(2)
    assert_reads(clock, SATURDAY_15_JUNE_2024[:5], 7, range(2, 5), f"{case}: ")


@pytest.mark.spec("S7-RTC-4")
def test_valid_set_after_a_refused_one(clock):
    assert clock.set(INVALID["30 February 2024"]).error == T_DATA_ERROR
    result = clock.set(T("24 02 29 09 00 00 00 01"))
    assert result.accepted, f"valid set after a refused one: {result}"
    assert_reads(clock, T("24 02 29 09 00 00 00 00")[:5], 5, range(0, 3))  # 29 Feb 2024 was a Thursday


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
        weekday = dt.date(year, 2, 29).isoweekday() % 7 + 1  # Python's calendar, independent of the PLC
        got = clock.read().buffer
        if got[:5] != buffer[:5] or got[7] != weekday:
            wrong.append(f"{year}: read {got.hex(' ').upper()}, weekday expected {weekday}")
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
def test_set_rtc_i_equals_set_rtc_with_bcd(set_i, integers, bcd_buffer, weekday):
    result = set_i.set_int(integers)
    assert result.accepted, f"SET_RTC_I refused {integers}: {result}"
    assert_reads(set_i, bcd_buffer[:5], weekday, range(0, 3), "SET_RTC_I: ")
    assert set_i.set(bcd_buffer).accepted
    assert_reads(set_i, bcd_buffer[:5], weekday, range(0, 3), "SET_RTC: ")


@pytest.mark.spec("S7-RTC-15", "S7-RTC-4")
@pytest.mark.parametrize("integers", [[24, 2, 30, 9, 0, 0, 0, 0], [23, 2, 29, 9, 0, 0, 0, 0],
                                      [24, 13, 1, 9, 0, 0, 0, 0],
                                      pytest.param([24, 6, 20, 24, 0, 0, 0, 0], marks=pytest.mark.spec("S7-RTC-6")),
                                      pytest.param([24, 6, 20, 9, 0, 0, 1, 0], marks=pytest.mark.spec("S7-RTC-6"))])
def test_set_rtc_i_refuses_what_set_rtc_refuses(set_i, integers):
    assert set_i.set(SATURDAY_15_JUNE_2024).accepted
    result = set_i.set_int(integers)
    assert (result.eno, result.error) == (0, T_DATA_ERROR), f"SET_RTC_I {integers}: {result}"
    assert_reads(set_i, SATURDAY_15_JUNE_2024[:5], 7, range(0, 3))


# -- edge-triggered --------------------------------------------------------------------------------------------
@pytest.mark.spec("S7-RTC-10")
def test_held_trigger_sets_once(bench, clock):
    """SET_RTC must run on a one-shot edge: holding the trigger does not keep setting the clock."""
    assert clock.set(T("24 06 15 08 30 00 00 07"), hold=True).accepted
    bench.wait(3)
    clock.write_set_buffer(T("24 01 01 01 01 01 00 02"))  # a new time while the trigger is still held
    bench.wait(2)
    assert_reads(clock, T("24 06 15 08 30 00 00 00")[:5], 7, range(5, 8), "trigger held 5 s: ")
    clock.release()
    assert clock.set(T("24 01 01 01 01 01 00 02")).accepted  # a fresh edge takes the new buffer
    assert_reads(clock, T("24 01 01 01 01 00 00 00")[:5], 2, range(1, 4))  # 1 Jan 2024 was a Monday


# -- power loss (emulator: power cycles on demand) -----------------------------------------------------------------
@pytest.mark.needs("power_cycle", reason="switches the CPU off and on")
@pytest.mark.spec("S7-RTC-13")
def test_power_loss_starts_at_2000_01_01_saturday(bench, clock):
    assert clock.set(T("24 06 15 08 30 00 00 07")).accepted
    bench.power_cycle(backup_expired=True)
    assert_reads(clock, T("00 01 01 00 00 00 00 00")[:5], 7, range(0, 2), "after the back-up ran out: ")


@pytest.mark.needs("power_cycle", reason="switches the CPU off and on")
@pytest.mark.spec("S7-RTC-14")
def test_power_cycle_keeps_the_time_only_with_an_rtc(bench, clock):
    assert clock.set(T("24 06 15 08 30 00 00 07")).accepted
    bench.wait(2)
    bench.power_cycle(backup_expired=False)
    if bench.settings.cpu in ("CR40", "CR60"):  # no RTC: the set value is lost at the next power cycle
        assert_reads(clock, T("00 01 01 00 00 00 00 00")[:5], 7, range(0, 2), f"{bench.settings.cpu}: ")
    else:
        assert_reads(clock, T("24 06 15 08 30 00 00 00")[:5], 7, range(2, 5), f"{bench.settings.cpu}: ")


# -- the CPU's own clock functions (S7 protocol: read/set the time of day) -----------------------------------------
@pytest.fixture
def cpu_clock(clock):
    if clock.cpu_clock() is None:
        pytest.skip("this wire has no clock functions: the S7 protocol has them (target s7+tcp://HOST:102)")
    return clock


@pytest.mark.spec("S7-WIRE-2")
def test_cpu_clock_function_reads_the_clock_read_rtc_reads(cpu_clock):
    assert cpu_clock.set(SATURDAY_15_JUNE_2024).accepted
    via_protocol = cpu_clock.cpu_clock()
    assert (via_protocol.year, via_protocol.month, via_protocol.day, via_protocol.hour, via_protocol.minute) == \
        (2024, 6, 15, 8, 30), f"the CPU clock function reads {via_protocol} after SET_RTC of 2024-06-15 08:30:00"
    assert via_protocol.second in range(0, 3), f"the CPU clock function reads {via_protocol}"
    assert_reads(cpu_clock, SATURDAY_15_JUNE_2024[:5], 7, range(0, 3), "after reading it with the clock function: ")


@pytest.mark.spec("S7-WIRE-2")
def test_cpu_clock_function_sets_what_read_rtc_reads(cpu_clock):
    cpu_clock.set_cpu_clock(dt.datetime(2012, 3, 4, 17, 45, 10))
    assert_reads(cpu_clock, T("12 03 04 17 45 10 00 01")[:5], 1, range(10, 13), "set with the clock function: ")
