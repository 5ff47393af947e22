"""The S7-200 SMART suites pass on the emulator over Modbus/TCP, skip across families with the reason, and fail
on deliberately broken S7 emulators (supplied through the ``pytest_hil_make_emulator`` hook)."""

from __future__ import annotations

import concurrent.futures
import datetime as dt
import math
import re
import subprocess
import sys

import pytest

from hil.families.s7smart.protocol import timebuf
from hil.families.s7smart.sim.emulator import RtcTestProgram, S7Clock, build_s7_emulator
from tests import broken_calendar as cal
from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import emulate_process

S7_BENCH = REPO / "fixtures" / "benches" / "s7-200smart.toml"
S7_SUITES = REPO / "suites" / "s7smart"
RTC_SUITE = "suites/s7smart/test_s7_rtc.py"


class BrokenS7:
    """Plugin object for an inner pytest run: the profile's S7 emulator with one model replaced."""

    def __init__(self, clock_cls: type[S7Clock] = S7Clock, program_cls: type[RtcTestProgram] = RtcTestProgram):
        self.clock_cls, self.program_cls = clock_cls, program_cls

    def pytest_hil_make_emulator(self, profile, epoch):
        emulator = build_s7_emulator(profile, epoch)
        for i, model in enumerate(emulator.models):
            if type(model) is S7Clock and self.clock_cls is not S7Clock:
                emulator.models[i] = self.clock_cls(has_rtc=model.has_rtc, start=model.start)
            elif type(model) is RtcTestProgram and self.program_cls is not RtcTestProgram:
                emulator.models[i] = self.program_cls(model.layout)
            emulator.models[i].power_on(emulator)
        return emulator


def broken_s7(defect: type) -> BrokenS7:
    """The profile's S7 emulator with ``defect`` in place of the model it subclasses (the clock or the program)."""
    return BrokenS7(program_cls=defect) if issubclass(defect, RtcTestProgram) else BrokenS7(defect)


def run_s7(pytester, *args: str, plugin: object | None = None, bench=S7_BENCH):
    recorder = pytester.inline_run(str(S7_SUITES), "--bench", str(bench), "-p", "no:cacheprovider", *args,
                                   plugins=[plugin] if plugin else [])
    passed, skipped, failed = recorder.listoutcomes()
    return [r.nodeid for r in passed], [r.nodeid for r in skipped], [r.nodeid for r in failed]


# -- the broken CPUs -----------------------------------------------------------------------------------------------
class WeekdayFromBuffer(S7Clock):
    """READ_RTC returns the weekday last written to SET_RTC instead of computing it."""

    written: int | None = None

    def set_rtc(self, now, buffer):
        error = super().set_rtc(now, buffer)
        if error == 0:
            self.written = buffer[7]
        return error

    def encode(self, when):
        data = super().encode(when)
        return data[:7] + bytes([self.written]) if self.written is not None else data


class LeapDayAlways(S7Clock):
    """Accepts 29 February in every year (loads 1 March in common years)."""

    def decode(self, buffer):
        try:
            return super().decode(buffer)
        except timebuf.TimeBufferError:
            if buffer[1:3] != b"\x02\x29":
                raise
            patched = super().decode(buffer[:2] + b"\x28" + buffer[3:])
            return patched + dt.timedelta(days=1)


class BcdNibbleUnchecked(S7Clock):
    """Reads each byte as 10·high + low nibble without checking the nibbles are 0–9 (16#1A → 20)."""

    def decode(self, buffer):
        fixed = bytes(timebuf.to_bcd(min(99, (b >> 4) * 10 + (b & 0xF))) for b in buffer)
        return super().decode(fixed)


class ReservedByteUnchecked(S7Clock):
    def decode(self, buffer):
        return super().decode(buffer[:6] + b"\x00" + buffer[7:])


class LevelTriggered(RtcTestProgram):
    """Runs the clock instructions on every scan while the trigger is 1 (no EU)."""

    def fires(self, previous, now):
        return bool(now)


class SetRtcIWithoutConversion(S7Clock):
    """SET_RTC_I hands its integers to SET_RTC as if they were BCD."""

    def set_rtc_i(self, now, buffer):
        return self.set_rtc(now, buffer)


class SetRtcITakesBytesModulo100(S7Clock):
    """SET_RTC_I converts each integer modulo 100: a byte above 99 becomes a valid one (minute 100 → 00)."""

    def set_rtc_i(self, now, buffer):
        return self.set_rtc(now, bytes(timebuf.to_bcd(b % 100) for b in bytes(buffer)))


class NoClockStartsAtTheHostTime(S7Clock):
    """A CPU without a clock (CR40/CR60) starts at the host's time at power-on instead of 2000-01-01 (a power
    cycle still loses it)."""

    def power_on(self, emu):
        super().power_on(emu)
        if not self.has_rtc:
            self._anchor = dt.datetime.now().replace(microsecond=0)


class PowerLossKeepsTime(S7Clock):
    """After the back-up ran out the clock restarts at its build time instead of 2000-01-01."""

    def power_cycle(self, emu, *, backup_expired):
        pass


VARIANTS = [  # (plugin, a suite test that must catch it)
    (BrokenS7(WeekdayFromBuffer), "test_weekday_ignored_on_write_and_computed_on_read"),
    (BrokenS7(LeapDayAlways), "test_29_february_refused_in_common_years"),
    (BrokenS7(BcdNibbleUnchecked), "test_illegal_bytes_are_not_written"),
    (BrokenS7(ReservedByteUnchecked), "test_illegal_bytes_are_not_written"),
    (BrokenS7(program_cls=LevelTriggered), "test_held_trigger_sets_once"),
    (BrokenS7(SetRtcIWithoutConversion), "test_set_rtc_i_equals_set_rtc_with_bcd"),
    (BrokenS7(PowerLossKeepsTime), "test_power_loss_starts_at_2000_01_01_saturday"),
]


# -- defects only the whole-domain checks catch (issue 26) -----------------------------------------------------------
HOUR_MONTH_SECOND = (1, 3, 5)  # the buffer bytes the first suite never gave a non-BCD nibble


class BcdUncheckedInHourMonthSecond(S7Clock):
    """Checks the nibbles of year, day and minute, but reads month, hour and second as 10·high + low (16#0A → 10)."""

    def decode(self, buffer):
        fixed = bytes(timebuf.to_bcd(min(99, (b >> 4) * 10 + (b & 0xF))) if i in HOUR_MONTH_SECOND else b
                      for i, b in enumerate(buffer))
        return super().decode(fixed)


class NonBcdHourMonthSecondGives0006(S7Clock):
    """Refuses a non-BCD month, hour or second with error 0006H instead of 0007H."""

    def set_rtc(self, now, buffer):
        if any(timebuf.from_bcd(buffer[i]) is None for i in HOUR_MONTH_SECOND):
            return timebuf.ERROR_INDIRECT
        return super().set_rtc(now, buffer)


class DayRangeOffByOne(S7Clock):
    """Takes day 32 for the 1st of the next month (the day's range checked as 01–32)."""

    def decode(self, buffer):
        if buffer[2] == 0x32:
            return super().decode(buffer[:2] + b"\x31" + buffer[3:]) + dt.timedelta(days=1)
        return super().decode(buffer)


class ValidatesMonthsAlternate(S7Clock):
    """Checks the day against a month table of 30 + month % 2 (31 September accepted as 1 October)."""

    def decode(self, buffer):
        month, day = timebuf.from_bcd(buffer[1]), timebuf.from_bcd(buffer[2])
        if month in range(1, 13) and month != 2 and day == 31:
            if 30 + month % 2 < 31:
                raise timebuf.TimeBufferError(["day"])
            return super().decode(buffer[:2] + b"\x30" + buffer[3:]) + dt.timedelta(days=1)
        return super().decode(buffer)


class _CalendarClock(S7Clock):
    """A clock whose own day counter has the month lengths of ``days_in`` (SET_RTC validates right)."""

    days_in = staticmethod(cal.true_days)

    def read_rtc(self, now):
        a = self._anchor
        elapsed = math.floor(now - self._anchor_now + 1e-9)
        fields, days = cal.count_on(a.year - 2000, a.month, a.day, a.hour, a.minute, a.second, elapsed,
                                    self.days_in)
        weekday = (timebuf.weekday(a.date()) - 1 + days) % 7 + 1
        return bytes(timebuf.to_bcd(v) for v in (*fields, 0)) + bytes([weekday]), timebuf.ERROR_NONE


class RunningFebruaryHas28(_CalendarClock):
    days_in = staticmethod(cal.february_always_28)


class RunningYear2000Common(_CalendarClock):
    days_in = staticmethod(cal.year_2000_common)


class RunningMonthsAlternate(_CalendarClock):
    days_in = staticmethod(cal.months_alternate)


# -- defects of the rules two tests hold (issue 39): the second test must catch each on its own --------------------
class RunningEveryMonth30(_CalendarClock):
    """The day counter of every month ends at 30: 30 January 23:59:59 is followed by 1 February."""

    days_in = staticmethod(cal.every_month_30)


class FiresOnBothEdges(RtcTestProgram):
    """Runs the clock instructions on the trigger's rise and again on its fall (a P and an N contact)."""

    def fires(self, previous, now):
        return bool(now) != bool(previous)


# -- the end of the clock's range: 2099 → 2000 (issue 39) --------------------------------------------------------
class _CenturyRunsOn(S7Clock):
    """A clock that counts on past 2099-12-31 23:59:59 into 2100 (no two-digit wrap); ``show_2100`` is what
    READ_RTC makes of a time in 2100."""

    def time(self, now):
        return self._anchor + dt.timedelta(seconds=math.floor(now - self._anchor_now + 1e-9))

    def encode(self, when):
        return super().encode(when) if when.year < 2100 else self.show_2100(when)

    def show_2100(self, when: dt.datetime) -> bytes:
        raise NotImplementedError


class YearCarriesInto2100(_CenturyRunsOn):
    """The BCD year counter carries past 99: 2100-01-01 reads as year 16#A0, with 2100's weekday (Friday, 6)."""

    def show_2100(self, when):
        in_2000 = super().encode(when.replace(year=when.year - 100))
        return bytes([0xA0]) + in_2000[1:7] + bytes([timebuf.weekday(when.date())])


class WeekdayCountsOnInto2100(_CenturyRunsOn):
    """The year shows 00, but the weekday is counted on from 2099-12-31: 2100-01-01's Friday (6), not Saturday."""

    def show_2100(self, when):
        in_2000 = super().encode(when.replace(year=when.year - 100))
        return in_2000[:7] + bytes([timebuf.weekday(when.date())])


class ClockStopsAtTheEndOf2099(_CenturyRunsOn):
    """The clock stands at 2099-12-31 23:59:59 once it gets there."""

    def time(self, now):
        return min(super().time(now), dt.datetime(2099, 12, 31, 23, 59, 59))


#: (defect, the suite test that must catch it: in process and against ``hil emulate --s7-tcp``); a rule two tests
#: hold has its defects listed with each
CAUGHT_BY = [
    (BcdUncheckedInHourMonthSecond, "test_illegal_bytes_are_not_written"),
    (NonBcdHourMonthSecondGives0006, "test_illegal_bytes_end_with_eno_0_and_0007"),
    (DayRangeOffByOne, "test_invalid_dates_refused_with_0007_and_the_clock_unchanged"),
    (ValidatesMonthsAlternate, "test_invalid_dates_refused_with_0007_and_the_clock_unchanged"),
    (RunningFebruaryHas28, "test_clock_runs_over_every_month_end_and_leap_day"),
    (RunningYear2000Common, "test_clock_runs_over_every_month_end_and_leap_day"),
    (RunningMonthsAlternate, "test_clock_runs_over_every_month_end_and_leap_day"),
    (SetRtcITakesBytesModulo100, "test_set_rtc_i_refuses_what_set_rtc_refuses"),
    (NoClockStartsAtTheHostTime, "test_a_cpu_without_a_clock_starts_at_2000_01_01"),
    (RunningFebruaryHas28, "test_clock_ticks_into_the_next_day_as_the_calendar_does"),
    (RunningYear2000Common, "test_clock_ticks_into_the_next_day_as_the_calendar_does"),
    (RunningMonthsAlternate, "test_clock_ticks_into_the_next_day_as_the_calendar_does"),
    (RunningEveryMonth30, "test_clock_ticks_into_the_next_day_as_the_calendar_does"),
    (RunningEveryMonth30, "test_clock_runs_over_every_month_end_and_leap_day"),
    (LevelTriggered, "test_clock_runs_under_a_held_trigger_and_each_new_edge_sets_it"),
    (FiresOnBothEdges, "test_clock_runs_under_a_held_trigger_and_each_new_edge_sets_it"),
    (YearCarriesInto2100, "test_clock_runs_from_2099_into_2000"),
    (WeekdayCountsOnInto2100, "test_clock_runs_from_2099_into_2000"),
    (ClockStopsAtTheEndOf2099, "test_clock_runs_from_2099_into_2000"),
]
#: defects only a CPU without a clock shows: run on the profile as a CR40
ON_A_CR40 = {NoClockStartsAtTheHostTime}


def cr40_text() -> str:
    return S7_BENCH.read_text().replace('cpu = "ST40"', 'cpu = "CR40"')
EMULATE_TIME_SCALE = 20.0


def _name(plugin: BrokenS7) -> str:
    return (plugin.clock_cls if plugin.clock_cls is not S7Clock else plugin.program_cls).__name__


@pytest.mark.parametrize("target", ["emulator+s7-tcp", "emulator+modbus-tcp", "emulator"])
def test_s7_suites_pass_on_the_emulator(pytester, target):
    passed, skipped, failed = run_s7(pytester, "--target", target)
    assert failed == []
    # (an ST40 has a real-time clock: the check of a CPU without one skips)
    skipped = [s for s in skipped if "test_a_cpu_without_a_clock_starts_at_2000_01_01" not in s]
    if target == "emulator+s7-tcp":  # the S7 protocol has the CPU's clock functions: nothing else to skip
        assert skipped == []
    else:  # only the clock-function tests skip (their reason names the s7+tcp:// wire)
        assert skipped and all("cpu_clock_function" in s for s in skipped), skipped
    assert len(passed) >= 30  # cases that share a wait are folded into one test each


@pytest.mark.parametrize("target", ["emulator+s7-tcp", pytest.param("emulator+modbus-tcp", marks=pytest.mark.matrix)])
@pytest.mark.parametrize("plugin, catcher", VARIANTS, ids=lambda v: _name(v) if isinstance(v, BrokenS7) else "")
def test_s7_suites_fail_on_broken_plc(pytester, plugin, catcher, target):
    _passed, _skipped, failed = run_s7(pytester, "--target", target, plugin=plugin)
    assert failed, f"no S7 suite test fails on a CPU with {_name(plugin)}: {type(plugin).__doc__}"
    assert any(catcher in f for f in failed), f"{catcher} did not catch {_name(plugin)}; failed: {failed}"


def test_families_deselect_each_other_with_the_reason(pytester):
    # FBs bench: S7 suites deselected, one line saying why (not a screen of identical skips, issue 24)
    result = pytester.runpytest_inprocess(str(S7_SUITES), "--bench", str(EMULATOR_BENCH), "-rs",
                                          "-p", "no:cacheprovider")
    passed, skipped, _failed = run_s7(pytester)  # (every S7 test: the CR40 one skips on this ST40)
    result.assert_outcomes(deselected=len(passed) + len(skipped))
    result.stdout.fnmatch_lines(["hil: * tests for s7-200smart PLCs deselected: bench 'emulator' is family 'fbs'"])
    assert "SKIPPED" not in result.stdout.str()
    # S7 bench: FBs smoke suite deselected
    result = pytester.runpytest_inprocess(str(REPO / "suites" / "test_smoke.py"), "--bench", str(S7_BENCH), "-rs",
                                          "-p", "no:cacheprovider")
    result.assert_outcomes(deselected=5)
    result.stdout.fnmatch_lines(["hil: 5 tests for fbs PLCs deselected: bench 's7-200smart emulator' is family "
                                 "'s7-200smart'"])


def test_cr40_loses_the_time_at_every_power_cycle(pytester, tmp_path):
    bench = tmp_path / "cr40.toml"
    bench.write_text(cr40_text())
    passed, skipped, failed = run_s7(pytester, "-k", "power or without_a_clock", bench=bench)
    assert failed == [] and len(passed) == 3

    class KeepsTime(S7Clock):  # a CR40 that behaves as if it had an RTC
        def power_cycle(self, emu, *, backup_expired):
            if backup_expired:
                super().power_cycle(emu, backup_expired=True)

    _p, _s, failed = run_s7(pytester, "-k", "power", bench=bench, plugin=BrokenS7(KeepsTime))
    assert [f for f in failed if "test_power_cycle_keeps_the_time_only_with_an_rtc" in f]


def test_an_fbs_emulator_on_an_s7_bench_is_refused(pytester):
    class WrongFamily:
        def pytest_hil_make_emulator(self, profile, epoch):
            from hil.families.fbs.sim import Emulator
            return Emulator()
    result = pytester.runpytest_inprocess(str(S7_SUITES / "test_s7_smoke.py"), "--bench", str(S7_BENCH),
                                          "-p", "no:cacheprovider", plugins=[WrongFamily()])
    assert result.ret == 4  # the bench never opens: one line with the reason, before anything is collected
    result.stderr.fnmatch_lines(["hil: error: cannot open bench *needs an S7 emulator*"])
    assert len([line for line in result.stderr.lines if line.strip()]) == 1, result.stderr.lines


@pytest.mark.parametrize("defect, catcher", CAUGHT_BY, ids=lambda v: v.__name__ if isinstance(v, type) else v)
def test_whole_domain_checks_catch_their_broken_cpu(pytester, defect, catcher):
    """The catcher run alone (``-k``): it fails on the defect without help from any other test."""
    bench = S7_BENCH
    if defect in ON_A_CR40:
        bench = pytester.path / "cr40.toml"
        bench.write_text(cr40_text())
    _passed, _skipped, failed = run_s7(pytester, "--target", "emulator", "-k", catcher, plugin=broken_s7(defect),
                                       bench=bench)
    assert any(catcher in f for f in failed), f"{catcher} did not catch {defect.__name__}"


def _against_hil_emulate(defect: type, catcher: str, tmp_path) -> tuple[str, bool, str]:
    spec = f"tests.test_s7_suites_catch_broken_plcs:broken_s7:{defect.__name__}"  # importable by hil emulate
    name = f"{defect.__name__}-{catcher}"
    served = S7_BENCH
    if defect in ON_A_CR40:
        served = tmp_path / f"{name}-served.toml"
        served.write_text(cr40_text())
    with emulate_process(served, EMULATE_TIME_SCALE, {"s7-tcp": "--s7-tcp"}, broken=spec) as endpoints:
        profile = tmp_path / f"{name}.toml"
        text = re.sub(r'(?m)^target = .*$', f'target = "s7+tcp://{endpoints["s7-tcp"]}"', served.read_text())
        # (a freshly started hil emulate is straight from power-on, as a bench's owner would declare)
        profile.write_text(text.replace("[bench]", f'[bench]\ntime_scale = {EMULATE_TIME_SCALE}\n'
                                        'offers = ["spec_choices", "power_on_state"]', 1))
        run = subprocess.run([sys.executable, "-m", "pytest", RTC_SUITE, "--bench", str(profile), "-q", "-rf",
                              "-p", "no:cacheprovider", "-p", "no:hypothesispytest", "-k", catcher],
                             cwd=REPO, capture_output=True, text=True, timeout=300)
    return name, f"FAILED {RTC_SUITE}::{catcher}" in run.stdout, run.stdout + run.stderr


@pytest.mark.matrix  # the in-process test above catches each; tests/test_s7_wire.py has the hil emulate path
@pytest.mark.timeout(600)
def test_whole_domain_checks_catch_their_broken_cpu_against_hil_emulate(tmp_path):
    """Each defect above served by ``hil emulate --s7-tcp`` as a separate real-time process, reached only over the
    S7 protocol: the test that catches it in process must fail there too."""
    with concurrent.futures.ThreadPoolExecutor(max_workers=4) as pool:
        results = list(pool.map(lambda case: _against_hil_emulate(*case, tmp_path), CAUGHT_BY))
    missed = [f"{name}:\n{out[-1500:]}" for name, caught, out in results if not caught]
    assert not missed, "defects their test does not catch against hil emulate:\n" + "\n".join(missed)
