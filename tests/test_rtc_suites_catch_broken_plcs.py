"""The RTC suites must fail on a PLC whose clock misbehaves — one deliberately broken emulator per defect."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from hil.families.fbs.rtc_time import CENTURY_SECONDS, FIELDS, RtcTime
from hil.families.fbs.sim.models.rtc import RtcModel
from tests import broken_calendar as cal
from tests.broken import BrokenEmulator, replace_model, run_suites
from tests.conftest import EMULATOR_BENCH

RTC_SUITES = ["test_rtc.py", "test_rtc_midnight.py", "test_rtc_validity.py", "test_rtc_adjust.py", "test_rtc_drift.py"]

HOLD, ADJUST, SET_ERROR, INSTALLED = 1952, 1953, 1955, 1954


class M1955NeverSet(RtcModel):
    def on_hold_edge(self, emu):
        super().on_hold_edge(emu)
        emu.memory.bits["M"][SET_ERROR] = 0


class LeapDayAlways(RtcModel):
    """Accepts 29 February in every year."""

    def validate(self, t):
        problems = super().validate(t)
        if t.month == 2 and t.day == 29:
            problems = [p for p in problems if p != "day"]
        return problems


class NoMinuteCarry(RtcModel):
    """±30 s rounds up the minute but never carries into the hour."""

    def apply_30s(self, t):
        if t.second < 30:
            return RtcTime(0, t.minute, t.hour, t.day, t.month, t.year, t.weekday)
        return RtcTime(0, (t.minute + 1) % 60, t.hour, t.day, t.month, t.year, t.weekday)


class WindowOffByOne(RtcModel):
    """Second 30 is treated as part of the drop window."""

    def apply_30s(self, t):
        if t.second == 30:
            t = RtcTime(29, t.minute, t.hour, t.day, t.month, t.year, t.weekday)
        return super().apply_30s(t)


class R4135Swapped(RtcModel):
    def copy_out(self, emu, t):
        super().copy_out(emu, t)
        emu.memory.words["R"][4135] = t.minute << 8 | t.hour


class SetOnRisingEdge(RtcModel):
    """Loads the chip when M1952 rises (from the registers as they are then) instead of when it falls."""

    def scan(self, emu):
        if emu.memory.bits["M"][HOLD] and not self._hold:
            RtcModel.on_hold_edge(self, emu)
        super().scan(emu)

    def on_hold_edge(self, emu):
        pass


class ReadOutWhileHeld(RtcModel):
    """Keeps copying the chip into R4128–R4135 while M1952 = 1."""

    def scan(self, emu):
        super().scan(emu)
        if emu.memory.bits["M"][HOLD]:
            self.copy_out(emu, self.read_chip(emu.now))


class D4054SignInverted(RtcModel):
    def correction_rate(self, code):
        return -super().correction_rate(code)


class WeekdayStuck(RtcModel):
    """The weekday stays what it was at the last set: it does not advance at midnight."""

    def weekday_after(self, days):
        return self._anchor_weekday


class M1954Cleared(RtcModel):
    def publish_chip(self, emu):
        super().publish_chip(emu)
        emu.memory.bits["M"][INSTALLED] = 0


class ClockStopsOnRefusal(RtcModel):
    """Refuses an invalid set correctly but stops the clock."""

    def on_hold_edge(self, emu):
        super().on_hold_edge(emu)
        if emu.memory.bits["M"][SET_ERROR]:
            self._rate = 0.0
            self._anchor_s = self.chip_seconds(emu.now)
            self._anchor_t = emu.now


class AdjustWhileHeld(RtcModel):
    """Applies the ±30 s correction on every scan M1953 is 1, not only on its rising edge."""

    def scan(self, emu):
        held = emu.memory.bits["M"][ADJUST] and self._adjust
        super().scan(emu)
        if held:
            self.on_adjust_edge(emu)


VARIANTS = [M1955NeverSet, LeapDayAlways, NoMinuteCarry, WindowOffByOne, R4135Swapped, SetOnRisingEdge,
            ReadOutWhileHeld, D4054SignInverted, WeekdayStuck, M1954Cleared, ClockStopsOnRefusal, AdjustWhileHeld]


# -- defects only the whole-domain checks catch (issue 26): each with the suite test that must catch it -----------
class _CalendarChip(RtcModel):
    """A chip whose own day counter has the month lengths of ``days_in`` once it has been set (the set itself is
    validated right, and the weekday counts on from the one written)."""

    days_in = staticmethod(cal.true_days)
    _base: tuple[RtcTime, float] | None = None

    def write_chip(self, emu, t):
        super().write_chip(emu, t)
        self._base = (t, self._anchor_s)

    def read_chip(self, now):
        if self._base is None:
            return super().read_chip(now)
        t, at = self._base
        elapsed = int(math.floor(self.chip_seconds(now) - at)) % CENTURY_SECONDS
        (year, month, day, hour, minute, second), days = cal.count_on(
            t.year, t.month, t.day, t.hour, t.minute, t.second, elapsed, self.days_in)
        return RtcTime(second, minute, hour, day, month, year, (t.weekday + days) % 7)


class RunningFebruaryHas28(_CalendarChip):
    """The running clock goes from 28 February to 1 March in leap years too."""

    days_in = staticmethod(cal.february_always_28)


class RunningYear2000Common(_CalendarChip):
    """The running clock takes 2000 for a common year (the century rule without its 400-year exception)."""

    days_in = staticmethod(cal.year_2000_common)


class RunningMonthsAlternate(_CalendarChip):
    """The running clock's month table is 30 + month % 2: August, October, December lose their 31st, September
    and November get one."""

    days_in = staticmethod(cal.months_alternate)


class SetTakesLowBytesOnly(RtcModel):
    """Validates and loads only the low byte of each of R4128–R4134 in ``fields`` (0105H is taken as 5)."""

    fields = FIELDS

    def on_hold_edge(self, emu):
        words = emu.memory.words["R"]
        for index, name in enumerate(FIELDS):
            if name in self.fields:
                words[4128 + index] &= 0xFF
        super().on_hold_edge(emu)


class ComparesSigned(RtcModel):
    """Compares signed, against the maximum only, the fields in ``fields`` (8000H–FFFFH pass as negative).

    Those are the fields whose minimum is 0, the lower bound a PLC may take for granted; the chip then takes what
    it is given."""

    fields = ("second", "minute", "hour", "year", "weekday")

    def validate(self, t):
        # a negative value passes `<= max`: validated as if it were 0, the one lower bound never checked
        registers = [0 if name in self.fields and value & 0x8000 else value
                     for name, value in zip(FIELDS, t.to_registers())]
        return super().validate(RtcTime.from_registers(registers))


def one_field(defect: type, field: str) -> type:
    """``defect`` confined to one register: the suite must catch it in each field, not only in some."""
    return type(f"{defect.__name__}In{field.capitalize()}", (defect,),
                {"fields": (field,), "__doc__": f"{defect.__doc__.splitlines()[0]}  Only the {field}."})


class LeapDayRefusedIn2000(RtcModel):
    """Refuses 29 February 2000 (the Gregorian century rule applied without its 400-year exception)."""

    def validate(self, t):
        return super().validate(t) or (["day"] if (t.year, t.month, t.day) == (0, 2, 29) else [])


class ValidatesMonthsAlternate(RtcModel):
    """Checks the day against a month table of 30 + month % 2 (31 September accepted, 31 August refused)."""

    def validate(self, t):
        problems = [p for p in super().validate(t) if p != "day"]
        if (1 <= t.month <= 12 and t.month != 2 and not 1 <= t.day <= 30 + t.month % 2
                or t.month == 2 and "day" in super().validate(t)):
            problems.append("day")
        return problems


class _AdjustCalendar(RtcModel):
    """The ±30 s carry counted with the month lengths of ``days_in``."""

    days_in = staticmethod(cal.true_days)

    def apply_30s(self, t):
        if t.second < 30:
            return RtcTime(0, t.minute, t.hour, t.day, t.month, t.year, t.weekday)
        (year, month, day, hour, minute, _), days = cal.count_on(
            t.year, t.month, t.day, t.hour, t.minute, 0, 60, self.days_in)
        return RtcTime(0, minute, hour, day, month, year, (t.weekday + days) % 7)


class AdjustCarryIgnoresLeapYears(_AdjustCalendar):
    days_in = staticmethod(cal.february_always_28)


class AdjustCarrySkipsThe31st(_AdjustCalendar):
    days_in = staticmethod(cal.every_month_30)


class AdjustWrapsInside2099(RtcModel):
    """The ±30 s correction wraps the year as soon as it is 2099 (a two-digit counter compared with 99 too early):
    a carry inside 2099 lands in 2000."""

    def apply_30s(self, t):
        fixed = super().apply_30s(t)
        return replace(fixed, year=0) if fixed.year == 99 else fixed


class AdjustWindowEndsAt58(RtcModel):
    """Second 59 is taken as part of the drop window."""

    def apply_30s(self, t):
        if t.second == 59:
            return RtcTime(0, t.minute, t.hour, t.day, t.month, t.year, t.weekday)
        return super().apply_30s(t)


class SetClearsTheWeekday(RtcModel):
    """A set loads R4128–R4133 but writes 0 (Sunday) into the chip's weekday counter, which counts on from there."""

    def write_chip(self, emu, t):
        super().write_chip(emu, t)
        self._anchor_weekday = 0


class WeekdayFromTheDateAtASet(RtcModel):
    """A set loads the date's weekday into the chip's counter, not the one written (it counts on from there)."""

    def write_chip(self, emu, t):
        super().write_chip(emu, t)
        self._anchor_weekday = t.with_weekday_from_date().weekday


class CalendarWeekday(RtcModel):
    """Computes the weekday from the date instead of counting it on: Saturday after the 2099 → 2000 wrap."""

    def read_chip(self, now):
        return super().read_chip(now).with_weekday_from_date()


class R4135OnlyAtASet(RtcModel):
    """Writes R4135 only when the chip is loaded (a set, a ±30 s correction): the read-out copies R4128–R4134."""

    def copy_out(self, emu, t):
        emu.memory.words["R"][4128:4135] = t.to_registers()

    def write_chip(self, emu, t):
        super().write_chip(emu, t)
        emu.memory.words["R"][4135] = t.hour_minute_word()


class SetNeedsM1952HeldThreeScans(RtcModel):
    """Loads the chip at M1952's fall only if M1952 was 1 for at least 3 scans (a debounced trigger)."""

    _held = 0  # scans M1952 has been 1 in a row, up to the last scan
    _held_before_fall = 0

    def scan(self, emu):
        if emu.memory.bits["M"][HOLD]:
            self._held += 1
        else:
            self._held_before_fall, self._held = self._held, 0
        super().scan(emu)

    def on_hold_edge(self, emu):
        if self._held_before_fall >= 3:
            super().on_hold_edge(emu)


class D4054NegativeCodesIgnored(RtcModel):
    """Applies only the codes of a clock that runs fast (S > 0): 5603H, 5602H … change nothing."""

    def correction_rate(self, code):
        return max(super().correction_rate(code), 0.0)


class D4054NegativeCodesInverted(RtcModel):
    """Applies the codes of a clock that runs slow with the wrong sign: 5602H slows it by 16.88 s/day."""

    def correction_rate(self, code):
        return abs(super().correction_rate(code))


class D4054DroppedAtASet(RtcModel):
    """A set loads the chip's time and resets its rate adjustment, though D4054 still holds the code."""

    def write_chip(self, emu, t):
        super().write_chip(emu, t)
        self._rate = self.chip_rate(0)


class D4054ZeroesSingleSteps(RtcModel):
    """Takes a code of ±1 step for noise and clears D4054 (5681H, 56FFH never read back)."""

    def scan(self, emu):
        words = emu.memory.words["D"]
        if words[4054] in (0x5681, 0x56FF):
            words[4054] = 0
        super().scan(emu)


class NoChipStillReadsOut(RtcModel):
    """No chip (D4053 = 0, M1954 = 0), yet every scan copies a software clock into R4128–R4135."""

    def scan(self, emu):
        super().scan(emu)
        if not emu.memory.bits["M"][HOLD]:
            self.copy_out(emu, self.read_chip(emu.now))


class NoChipM1954Set(RtcModel):
    """No chip (D4053 = 0) but M1954 = 1."""

    def publish_chip(self, emu):
        super().publish_chip(emu)
        emu.memory.bits["M"][INSTALLED] = 1


#: defect → the suite test that must catch it (in process here, against ``hil emulate`` in
#: tests/test_broken_plcs_on_a_bench.py)
CAUGHT_BY = {
    RunningFebruaryHas28: "test_clock_runs_over_every_month_end_and_midnight",
    RunningYear2000Common: "test_clock_runs_over_every_month_end_and_midnight",
    RunningMonthsAlternate: "test_clock_runs_over_every_month_end_and_midnight",
    SetTakesLowBytesOnly: "test_every_invalid_field_is_refused_with_m1955_and_the_clock_runs_on",
    LeapDayRefusedIn2000: "test_leap_day_accepted_in_leap_years_2000_to_2096",
    ValidatesMonthsAlternate: "test_every_invalid_field_is_refused_with_m1955_and_the_clock_runs_on",
    AdjustCarryIgnoresLeapYears: "test_adjust_30s_carries_into_hour_day_every_month_and_year",
    AdjustCarrySkipsThe31st: "test_adjust_30s_carries_into_hour_day_every_month_and_year",
    AdjustWindowEndsAt58: "test_adjust_30s_over_both_windows_and_their_edges",
    AdjustWrapsInside2099: "test_adjust_30s_carries_into_hour_day_every_month_and_year",
    SetClearsTheWeekday: "test_set_then_read_round_trip_of_every_field_edge_and_weekday",
    CalendarWeekday: "test_adjust_30s_carry_from_2099_wraps_to_2000",
    WeekdayFromTheDateAtASet: "test_weekday_written_is_kept_and_counts_on_from_itself",
    D4054ZeroesSingleSteps: "test_d4054_write_read_back_of_every_table_1_code",
    SetNeedsM1952HeldThreeScans: "test_set_takes_a_one_scan_pulse_of_m1952",
    D4054NegativeCodesIgnored: "test_d4054_largest_codes_of_both_signs_change_the_rate_by_table_1s_amount",
    D4054NegativeCodesInverted: "test_d4054_largest_codes_of_both_signs_change_the_rate_by_table_1s_amount",
    D4054DroppedAtASet: "test_d4054_correction_stays_in_force_across_a_set_of_the_clock",
    R4135OnlyAtASet: "test_r4135_follows_the_running_clock_across_a_minute_an_hour_and_midnight",
    NoChipStillReadsOut: "test_without_a_chip_d4053_is_0_m1954_is_0_and_r4128_r4135_are_not_updated",
    NoChipM1954Set: "test_without_a_chip_d4053_is_0_m1954_is_0_and_r4128_r4135_are_not_updated",
}
#: every field's register-width check, field by field (the weekday's range is RTC-VAL-5's, tested apart)
for _field in FIELDS:
    _test = ("test_weekday_out_of_range_is_refused_with_m1955_and_the_clock_runs_on" if _field == "weekday" else
             CAUGHT_BY[SetTakesLowBytesOnly])
    for _defect in (SetTakesLowBytesOnly, ComparesSigned):
        if _field in _defect.fields:
            _variant = one_field(_defect, _field)
            globals()[_variant.__name__] = _variant  # by name, as tests/broken_emulate.py looks a defect up
            CAUGHT_BY[_variant] = _test
#: defects of a PLC without an RTC chip: run on the profile that says so
NO_CHIP = {NoChipStillReadsOut, NoChipM1954Set}


def no_chip_profile(text: str) -> str:
    """An emulator profile with no RTC chip ([rtc] chip = "none")."""
    assert 'chip = "S-35390A"' in text
    return text.replace('chip = "S-35390A"', 'chip = "none"', 1)


def with_rtc(cls):
    def breakage(emulator, profile, epoch):
        rtc = profile.rtc
        replace_model(emulator, RtcModel, cls(chip=rtc.chip, crystal_ppm=rtc.crystal_ppm, start=rtc.start or epoch))
    return BrokenEmulator(breakage)


def test_correct_emulator_passes_every_rtc_suite(pytester):
    passed, failed = run_suites(pytester, RTC_SUITES)
    assert failed == []
    assert len(passed) >= 20  # cases that share a wait are folded into one test each


@pytest.mark.parametrize("variant", VARIANTS, ids=lambda cls: cls.__name__)
def test_rtc_suites_fail_on_broken_plc(pytester, variant):
    passed, failed = run_suites(pytester, RTC_SUITES, with_rtc(variant))
    assert failed, f"no RTC suite test fails on a PLC with {variant.__name__}: {variant.__doc__ or ''}"
    print(f"{variant.__name__}: {len(failed)} failing, e.g. {failed[0]}")




class M1955KeptByAnAcceptedSet(RtcModel):
    """Not a defect: M1955 := 1 on a refusal, and an accepted set leaves it as it was — the reading of the manual the
    spec's [our choice] RTC-VAL-4 ("an accepted set clears M1955") sets aside."""

    def on_hold_edge(self, emu):
        earlier = emu.memory.bits["M"][SET_ERROR]
        super().on_hold_edge(emu)
        emu.memory.bits["M"][SET_ERROR] |= earlier


def test_only_the_rtc_val_4_test_leans_on_an_accepted_set_clearing_m1955(pytester):
    """The harness judges a set after an earlier refusal by the clock read back, not by M1955 (Rtc._finish_set),
    so the suites' sets and the guard's clock restore work on such a PLC: the one test marked RTC-VAL-4 fails (a
    bench without spec_choices skips it), every other passes."""
    passed, failed = run_suites(pytester, RTC_SUITES, with_rtc(M1955KeptByAnAcceptedSet))
    assert [f.split("::")[-1] for f in failed] == ["test_valid_set_after_a_refused_one_clears_m1955"], failed
    assert len(passed) >= 20


@pytest.fixture
def no_chip_bench(tmp_path):
    bench = tmp_path / "no-chip.toml"
    bench.write_text(no_chip_profile(EMULATOR_BENCH.read_text()))
    return bench


def test_correct_emulator_without_a_chip_passes_every_rtc_suite(pytester, no_chip_bench):
    passed, failed = run_suites(pytester, RTC_SUITES, bench=no_chip_bench)
    assert failed == []
    assert any(CAUGHT_BY[NoChipM1954Set] in p for p in passed), passed


@pytest.mark.parametrize("variant", list(CAUGHT_BY), ids=lambda cls: cls.__name__)
def test_whole_domain_checks_catch_their_broken_plc(pytester, variant, no_chip_bench):
    bench = no_chip_bench if variant in NO_CHIP else EMULATOR_BENCH
    passed, failed = run_suites(pytester, RTC_SUITES, with_rtc(variant), bench=bench)
    assert any(CAUGHT_BY[variant] in f for f in failed), (
        f"{CAUGHT_BY[variant]} does not fail on a PLC with {variant.__name__}: {variant.__doc__ or ''}; "
        f"failed: {failed}")
