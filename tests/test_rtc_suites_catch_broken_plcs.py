"""The RTC suites must fail on a PLC whose clock misbehaves — one deliberately broken emulator per defect."""

from __future__ import annotations


import pytest

from hil.families.fbs.sim.models.rtc import RtcModel
from hil.families.fbs.rtc_time import RtcTime
from tests.broken import BrokenEmulator, replace_model, run_suites

RTC_SUITES = ["test_rtc.py", "test_rtc_validity.py", "test_rtc_adjust.py", "test_rtc_drift.py"]

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

    _stuck: int | None = None

    def write_chip(self, emu, t):
        super().write_chip(emu, t)
        self._stuck = t.weekday

    def weekday_for(self, year, month, day):
        return self._stuck if self._stuck is not None else super().weekday_for(year, month, day)


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


def with_rtc(cls):
    def breakage(emulator, profile, epoch):
        rtc = profile.rtc
        replace_model(emulator, RtcModel, cls(chip=rtc.chip, crystal_ppm=rtc.crystal_ppm, start=rtc.start or epoch))
    return BrokenEmulator(breakage)


def test_correct_emulator_passes_every_rtc_suite(pytester):
    passed, failed = run_suites(pytester, RTC_SUITES)
    assert failed == []
    assert len(passed) >= 40


@pytest.mark.parametrize("variant", VARIANTS, ids=lambda cls: cls.__name__)
def test_rtc_suites_fail_on_broken_plc(pytester, variant):
    passed, failed = run_suites(pytester, RTC_SUITES, with_rtc(variant))
    assert failed, f"no RTC suite test fails on a PLC with {variant.__name__}: {variant.__doc__ or ''}"
    print(f"{variant.__name__}: {len(failed)} failing, e.g. {failed[0]}")


