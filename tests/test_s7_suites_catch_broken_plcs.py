"""The S7-200 SMART suites pass on the emulator over Modbus/TCP, skip across families with the reason, and fail
on deliberately broken S7 emulators (supplied through the ``pytest_hil_make_emulator`` hook)."""

from __future__ import annotations

import datetime as dt

import pytest

from hil.families.s7smart import timebuf
from hil.families.s7smart.emulator import RtcTestProgram, S7Clock, build_s7_emulator
from tests.conftest import EMULATOR_BENCH, REPO

S7_BENCH = REPO / "fixtures" / "benches" / "s7-200smart.toml"
S7_SUITES = REPO / "suites" / "s7smart"
RTC_SUITE = "suites/s7smart/test_s7_rtc.py"


class BrokenS7:
    """Plugin object for an inner pytest run: the profile's S7 emulator with one model replaced."""

    def __init__(self, clock_cls: type[S7Clock] = S7Clock, program_cls: type[RtcTestProgram] = RtcTestProgram):
        self.clock_cls, self.program_cls = clock_cls, program_cls

    def pytest_hil_make_emulator(self, profile, epoch):  # noqa: ANN001, ANN201
        emulator = build_s7_emulator(profile, epoch)
        for i, model in enumerate(emulator.models):
            if type(model) is S7Clock and self.clock_cls is not S7Clock:
                emulator.models[i] = self.clock_cls(has_rtc=model.has_rtc, start=model.start)
            elif type(model) is RtcTestProgram and self.program_cls is not RtcTestProgram:
                emulator.models[i] = self.program_cls(model.layout)
            emulator.models[i].power_on(emulator)
        return emulator


def run_s7(pytester, *args: str, plugin: object | None = None, bench=S7_BENCH):  # noqa: ANN001, ANN201
    recorder = pytester.inline_run(str(S7_SUITES), "--bench", str(bench), "-p", "no:cacheprovider", *args,
                                   plugins=[plugin] if plugin else [])
    passed, skipped, failed = recorder.listoutcomes()
    return [r.nodeid for r in passed], [r.nodeid for r in skipped], [r.nodeid for r in failed]


# -- the broken CPUs -----------------------------------------------------------------------------------------------
class WeekdayFromBuffer(S7Clock):
    """READ_RTC returns the weekday last written to SET_RTC instead of computing it."""

    written: int | None = None

    def set_rtc(self, now, buffer):  # noqa: ANN001, ANN201
        error = super().set_rtc(now, buffer)
        if error == 0:
            self.written = buffer[7]
        return error

    def encode(self, when):  # noqa: ANN001, ANN201
        data = super().encode(when)
        return data[:7] + bytes([self.written]) if self.written is not None else data


class LeapDayAlways(S7Clock):
    """Accepts 29 February in every year (loads 1 March in common years)."""

    def decode(self, buffer):  # noqa: ANN001, ANN201
        try:
            return super().decode(buffer)
        except timebuf.TimeBufferError:
            if buffer[1:3] != b"\x02\x29":
                raise
            patched = super().decode(buffer[:2] + b"\x28" + buffer[3:])
            return patched + dt.timedelta(days=1)


class BcdNibbleUnchecked(S7Clock):
    """Reads each byte as 10·high + low nibble without checking the nibbles are 0–9 (16#1A → 20)."""

    def decode(self, buffer):  # noqa: ANN001, ANN201
        fixed = bytes(timebuf.to_bcd(min(99, (b >> 4) * 10 + (b & 0xF))) for b in buffer)
        return super().decode(fixed)


class ReservedByteUnchecked(S7Clock):
    def decode(self, buffer):  # noqa: ANN001, ANN201
        return super().decode(buffer[:6] + b"\x00" + buffer[7:])


class LevelTriggered(RtcTestProgram):
    """Runs the clock instructions on every scan while the trigger is 1 (no EU)."""

    def fires(self, previous, now):  # noqa: ANN001, ANN201
        return bool(now)


class SetRtcIWithoutConversion(S7Clock):
    """SET_RTC_I hands its integers to SET_RTC as if they were BCD."""

    def set_rtc_i(self, now, buffer):  # noqa: ANN001, ANN201
        return self.set_rtc(now, buffer)


class PowerLossKeepsTime(S7Clock):
    """After the back-up ran out the clock restarts at its build time instead of 2000-01-01."""

    def power_cycle(self, emu, *, backup_expired):  # noqa: ANN001, ANN201
        pass


VARIANTS = [  # (plugin, a suite test that must catch it)
    (BrokenS7(WeekdayFromBuffer), "test_weekday_ignored_on_write_and_computed_on_read"),
    (BrokenS7(LeapDayAlways), "test_invalid_buffer_refused_with_0007[29 February 2023]"),
    (BrokenS7(BcdNibbleUnchecked), "test_invalid_buffer_refused_with_0007[non-BCD minute 16#1A]"),
    (BrokenS7(ReservedByteUnchecked), "test_invalid_buffer_refused_with_0007[reserved byte 01]"),
    (BrokenS7(program_cls=LevelTriggered), "test_held_trigger_sets_once"),
    (BrokenS7(SetRtcIWithoutConversion), "test_set_rtc_i_equals_set_rtc_with_bcd"),
    (BrokenS7(PowerLossKeepsTime), "test_power_loss_starts_at_2000_01_01_saturday"),
]


def _name(plugin: BrokenS7) -> str:
    return (plugin.clock_cls if plugin.clock_cls is not S7Clock else plugin.program_cls).__name__


@pytest.mark.parametrize("target", ["emulator+s7-tcp", "emulator+modbus-tcp", "emulator"])
def test_s7_suites_pass_on_the_emulator(pytester, target):
    passed, skipped, failed = run_s7(pytester, "--target", target)
    assert failed == []
    if target == "emulator+s7-tcp":  # the S7 protocol has the CPU's clock functions: nothing to skip
        assert skipped == []
    else:  # only the clock-function tests skip (their reason names the s7+tcp:// wire)
        assert skipped and all("cpu_clock_function" in s for s in skipped), skipped
    assert len(passed) >= 40


@pytest.mark.parametrize("target", ["emulator+s7-tcp", "emulator+modbus-tcp"])
@pytest.mark.parametrize("plugin, catcher", VARIANTS, ids=lambda v: _name(v) if isinstance(v, BrokenS7) else "")
def test_s7_suites_fail_on_broken_plc(pytester, plugin, catcher, target):
    _passed, _skipped, failed = run_s7(pytester, "--target", target, plugin=plugin)
    assert failed, f"no S7 suite test fails on a CPU with {_name(plugin)}: {type(plugin).__doc__}"
    assert any(catcher in f for f in failed), f"{catcher} did not catch {_name(plugin)}; failed: {failed}"


def test_families_deselect_each_other_with_the_reason(pytester):
    # FBs bench: S7 suites deselected, one line saying why (not a screen of identical skips, issue 24)
    result = pytester.runpytest_inprocess(str(S7_SUITES), "--bench", str(EMULATOR_BENCH), "-rs",
                                          "-p", "no:cacheprovider")
    result.assert_outcomes(deselected=len(run_s7(pytester)[0]))
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
    bench.write_text(S7_BENCH.read_text().replace('cpu = "ST40"', 'cpu = "CR40"'))
    passed, skipped, failed = run_s7(pytester, "-k", "power", bench=bench)
    assert failed == [] and len(passed) == 2

    class KeepsTime(S7Clock):  # a CR40 that behaves as if it had an RTC
        def power_cycle(self, emu, *, backup_expired):  # noqa: ANN001, ANN201
            if backup_expired:
                super().power_cycle(emu, backup_expired=True)

    _p, _s, failed = run_s7(pytester, "-k", "power", bench=bench, plugin=BrokenS7(KeepsTime))
    assert [f for f in failed if "test_power_cycle_keeps_the_time_only_with_an_rtc" in f]


def test_an_fbs_emulator_on_an_s7_bench_is_refused(pytester):
    class WrongFamily:
        def pytest_hil_make_emulator(self, profile, epoch):  # noqa: ANN001, ANN201
            from hil.families.fbs.sim import Emulator
            return Emulator()
    result = pytester.runpytest_inprocess(str(S7_SUITES / "test_s7_smoke.py"), "--bench", str(S7_BENCH),
                                          "-p", "no:cacheprovider", plugins=[WrongFamily()])
    assert result.ret == 4  # the bench never opens: one line with the reason, before anything is collected
    result.stderr.fnmatch_lines(["ERROR: hil: cannot open bench *needs an S7 emulator*"])
    assert len([line for line in result.stderr.lines if line.strip()]) == 1, result.stderr.lines
