"""The PID suites end to end: every emulator wire, the heater-loop test on virtual time, and broken FUN86 models that
the suites must catch (a suite that passes on a faulty PLC is the worst bug this project can have)."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest

import hil.families.fbs.device.pid
import hil.families.fbs.faults
import hil.families.fbs.sim.serve_fatek
import hil.families.fbs.sim.serve_modbus
import hil.families.fbs.transport.fatek
import hil.families.fbs.transport.local
import hil.families.fbs.transport.modbus
import hil.plugin.pytest_plugin  # noqa: F401
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.models.fun86 import Fun86Model
from hil.families.fbs.sim.models.temperature import TemperatureModel
from hil.families.fbs.temperature import decode_start
from tests.broken import replace_model
from tests.conftest import EMULATOR_BENCH, REPO, over_targets

SUITES = [str(REPO / "suites" / "test_pid.py"), str(REPO / "suites" / "test_pid_control.py")]
SUITE_TESTS = 36  # the pre-alarm scan counts bracketed with the scan counter the emulator's profile declares
INNER = ("-p", "no:hypothesispytest", "-p", "no:cacheprovider")


# (FATEK/TCP too in the matrix: the gate's bench-mode run takes every PID suite over it against hil emulate)
@pytest.mark.parametrize("target", over_targets("emulator+modbus-rtu", "emulator+fatek-serial", "emulator+modbus-tcp",
                                                "emulator+fatek-tcp"))
def test_pid_suites_pass_on_every_emulator_target(pytester, target):
    result = pytester.runpytest_inprocess(*SUITES, *INNER, "--bench", str(EMULATOR_BENCH), "--target", target)
    result.assert_outcomes(passed=SUITE_TESTS)


def test_without_a_scan_counter_the_scan_counts_skip_saying_how_to_declare_one(pytester, tmp_path):
    bench = tmp_path / "bench.toml"
    bench.write_text(EMULATOR_BENCH.read_text().replace('scan_counter = "R3999"', "", 1))
    result = pytester.runpytest_inprocess(SUITES[0], *INNER, "--bench", str(bench), "-k", "consecutive_scans",
                                          "-rs")
    result.assert_outcomes(skipped=3)
    result.stdout.fnmatch_lines(["*needs scan_counter*[[]bench[]] scan_counter = *"])


def test_the_heater_loop_test_passes_on_the_emulator_on_virtual_time(pytester, monkeypatch):
    """R4007's minute (and the PID intervals before it) pass on the emulator's clock: bench time the test took,
    from its JUnit property, against what the host was asked to sleep — counted, not timed (its wall time is a
    benchmark's figure: benchmarks/bench_host_time.py)."""
    slept: list[float] = []
    sleep = time.sleep
    monkeypatch.setattr(time, "sleep", lambda seconds: (slept.append(seconds), sleep(seconds))[1])
    result = pytester.inline_run(SUITES[1], *INNER, "--bench", str(EMULATOR_BENCH), "-k", "r4007_seconds")
    result.assertoutcome(passed=2)  # R4007 = 60 s and 256 s
    properties = dict(p for r in result.getreports("pytest_runtest_logreport") for p in r.user_properties)
    assert float(properties["hil_virtual_s"]) >= 60, properties  # R4007 = 60 s (its minimum) and more of bench time…
    assert sum(slept) < 1.0, f"…but the host slept {sum(slept):.1f} s of it"  # …none of it slept on the host


# The heater-loop checks against hil emulate reached only over the wire, heaters opened through the Modbus
# coil rig: tests/test_bench_mode.py (its heater-loop runs, over FATEK/TCP and Modbus/TCP).


# -- broken FUN86 models -------------------------------------------------------------------------------------------
class PrealarmAfter9Scans(Fun86Model):
    def prealarm(self, count):
        return count >= 9


class PrealarmAfter11Scans(Fun86Model):
    def prealarm(self, count):
        return count >= 11


class DipDoesNotResetTheCount(Fun86Model):
    def prealarm_count(self, count, pv, limit):
        return np.where(pv >= limit, count + 1, count)


class BandEdgesExclusive(Fun86Model):
    def in_band(self, pv, sv, os):
        return (sv - os < pv) & (pv < sv + os)


class LowPointsInSecondWord(Fun86Model):
    """WR+1/WR+3 used for points Sn+0…15 (and WR+0/WR+2 for the rest)."""

    def bit_position(self, b):
        return 1 - b // 16, b % 16


class AlmIgnoresWarnings(Fun86Model):
    def alarm(self, enabled_not_normal, any_warning):
        return enabled_not_normal


class HeaterLoopTimerTwiceAsFast(Fun86Model):
    def loop_elapsed(self, since, now):
        return 2 * (now - since)


class HeaterLoopTimerHalfSpeed(Fun86Model):
    def loop_elapsed(self, since, now):
        return (now - since) / 2


class HeaterLoopIgnoresR4006(Fun86Model):
    """Always uses the default 90 %."""

    def loop_threshold(self, mem):
        return 90


class HeaterLoopOnePercentEarly(Fun86Model):
    """Counts an output from R4006 − 1 % as high: one just under R4006 warns."""

    def loop_threshold(self, mem):
        return super().loop_threshold(mem) - 1


class HeaterLoopOnePercentLate(Fun86Model):
    """Counts an output as high only from R4006 + 1 %: one just at or above R4006 never warns."""

    def loop_threshold(self, mem):
        return super().loop_threshold(mem) + 1


class NoDerivativeAction(Fun86Model):
    """The law without its D term: Td has no effect."""

    def law(self, inst, kc, ki, td, heating, ts):
        law = super().law(inst, kc, ki, td, heating, ts)
        return dataclasses.replace(law, derivative=law.derivative * 0)


class TdInWholeMinutes(Fun86Model):
    """Td taken in whole minutes (its 0.01 min truncated): a Td under a minute has no D term."""

    def law(self, inst, kc, ki, td, heating, ts):
        return super().law(inst, kc, ki, np.asarray(td) // 100 * 100, heating, ts)


class NoErrForSnPlusZn33(Fun86Model):
    def valid(self, sn, zn):
        return 0 <= sn <= 31 and 1 <= zn <= 32 and sn + zn <= 33


class DisabledPointStillDriven(Fun86Model):
    def drive(self, enabled, on):
        return on


class R4004Ignored(Fun86Model):
    """PVs always from the table's readings, whatever R4003/R4004 say."""

    def readings_start(self, mem):
        words = mem.words["R"]
        saved = words[4003]
        words[4003] = 0
        try:
            return super().readings_start(mem)
        finally:
            words[4003] = saved


class R4004DBankRejected(Fun86Model):
    """R4004 = 20000–23999 (D0–D3999) not taken: the table's readings instead."""

    def readings_start(self, mem):
        start = super().readings_start(mem)
        if start is not None and start.kind == "D" and mem.words["R"][4003] == 0xA55A:
            return decode_start(mem.words[self.temperature.table.kind][self.temperature.table.index + 2])
        return start


class R4004UpperEdgesRejected(Fun86Model):
    """R4004 = 13839 and 23999, the last codes of each bank, not taken."""

    def readings_start(self, mem):
        if mem.words["R"][4003] == 0xA55A and mem.words["R"][4004] in (13839, 23999):
            return decode_start(mem.words[self.temperature.table.kind][self.temperature.table.index + 2])
        return super().readings_start(mem)


class R4004PastTheEndTaken(Fun86Model):
    """R4004 = 13840 and 24000 (past each bank's range) taken as R3840 / D4000."""

    def readings_start(self, mem):
        if mem.words["R"][4003] == 0xA55A and mem.words["R"][4004] in (13840, 24000):
            return decode_start(mem.words["R"][4004])
        return super().readings_start(mem)


class R4003KeyIgnored(Fun86Model):
    """R4004 taken whatever R4003 holds."""

    def readings_start(self, mem):
        code = mem.words["R"][4004]
        if 10000 <= code <= 13839 or 20000 <= code <= 23999:
            return decode_start(code)
        return super().readings_start(mem)


class BandComparedUnsigned(Fun86Model):
    """SV − Os ≤ PV ≤ SV + Os compared as unsigned words: a band below 0 never holds."""

    def in_band(self, pv, sv, os):
        pv, sv, os = (np.asarray(x, dtype=np.int64) & 0xFFFF for x in (pv, sv, os))
        return ((sv - os) & 0xFFFF <= pv) & (pv <= (sv + os) & 0xFFFF)


class AlmIgnoresTheSecondWords(Fun86Model):
    """ALM from points Sn…Sn + 15 only (WR+0/WR+2): a point of WR+1/WR+3 alone never raises it."""

    def scan(self, emu):
        super().scan(emu)
        mem = emu.memory
        for inst in self.config.instances:
            if not mem.bits[inst.en.kind][inst.en.index] or inst.settable:
                continue
            wr = mem.words[inst.wr.kind][inst.wr.index:inst.wr.index + 4]
            points = range(inst.sn, inst.sn + min(inst.zn, 16))
            enabled = self.enabled(mem, np.array(list(points)))
            expected = sum(1 << (p - inst.sn) for p, e in zip(points, enabled) if e)
            mem.bits[inst.alm.kind][inst.alm.index] = int((wr[0] & expected) != expected or wr[2] != 0)


class PrealarmOnlyAboveR4008(Fun86Model):
    """PV > R4008, not PV ≥ R4008."""

    def prealarm_count(self, count, pv, limit):
        return np.where(pv > limit, count + 1, 0)


class PrealarmLimitSigned(Fun86Model):
    """R4008 read as a signed word: 40000 (4000.0 °) is below every PV."""

    def prealarm_count(self, count, pv, limit):
        return np.where(pv >= (limit - 65536 if limit > 32767 else limit), count + 1, 0)


class PrealarmPvUnsigned(Fun86Model):
    """PV read as an unsigned word: −100.0 ° counts as 6453.6 °, above R4008."""

    def prealarm_count(self, count, pv, limit):
        return np.where((np.asarray(pv, dtype=np.int64) & 0xFFFF) >= limit, count + 1, 0)


class R4013Ignored(Fun86Model):
    """Every point's enable bit taken from R4012 (point % 16)."""

    def enabled(self, mem, point):
        return super().enabled(mem, np.asarray(point) % 16)


class ActsBeforeMeasured(Fun86Model):
    """Runs at once, not only after every fitted point has been measured."""

    def all_measured(self, mem):
        return True


class CoolingHeats(Fun86Model):
    """H/C ignored: every box heats."""

    def law(self, inst, kc, ki, td, heating, ts):
        return super().law(inst, kc, ki, td, True, ts)


class R4005AppliedAtOnce(Fun86Model):
    """A new PID interval in R4005 takes effect at once, with EN held."""

    def scan(self, emu):
        for st in self.states:
            if st.running:
                interval, pwm = self.timing(emu.memory.words["R"][4005])
                if interval != st.interval:
                    st.interval, st.pwm = interval, pwm
                    st.next_pid = min(st.next_pid, emu.now + interval)
        super().scan(emu)


class PwmInverted(Fun86Model):
    """Y ON for 1 − OR/16383 of each PWM period (the duty inverted)."""

    def waves(self, st, enabled, output):
        on_time, y_on, y_off = super().waves(st, enabled, output)
        return st.pwm - on_time, y_on, y_off


class OutputClampedAt10000(Fun86Model):
    """OR never above 10000 (61 %)."""

    def control(self, law, integral, pv_prev, has_prev, sv, pv):
        out, integral = super().control(law, integral, pv_prev, has_prev, sv, pv)
        return np.minimum(out, 10000.0), integral


class KiZeroStillIntegrates(Fun86Model):
    """Ki = 0 taken as Ki = 100: integral action where the manual says none."""

    def law(self, inst, kc, ki, td, heating, ts):
        return super().law(inst, kc, np.where(np.asarray(ki) == 0, 100, ki), td, heating, ts)


class Zn32Refused(Fun86Model):
    """Zn = 32 (the largest) refused with ERR."""

    def valid(self, sn, zn):
        return super().valid(sn, zn) and zn < 32


class PwmPeriodFromTheLowByte(Fun86Model):
    """The PWM period taken from R4005's low byte too (4 s at 0102H instead of 2 s)."""

    def timing(self, r4005):
        interval, _pwm = super().timing(r4005)
        return interval, interval


class SecondWordsKeepFourBits(Fun86Model):
    """WR+1/WR+3 keep only bits 0–3 (points Sn + 16 … Sn + 19, as far as the default boxes reach)."""

    def bit_words(self, st, bits):
        first, second = super().bit_words(st, bits)
        return first, second & 0x000F


class R4005NotClamped(Fun86Model):
    """R4005 codes past 5 not clamped: 2^code s in both bytes (code 6: 64 s)."""

    def timing(self, r4005):
        return 2.0 ** (r4005 & 0xFF), 2.0 ** (r4005 >> 8)


class R4005ClampedInTheLowByteOnly(Fun86Model):
    """The PID interval clamped at 32 s, the PWM period (high byte) not: 2^code s."""

    def timing(self, r4005):
        interval, _pwm = super().timing(r4005)
        return interval, 2.0 ** (r4005 >> 8)


class R4005ClampedInTheHighByteOnly(Fun86Model):
    """The PWM period clamped at 32 s, the PID interval (low byte) not: 2^code s."""

    def timing(self, r4005):
        _interval, pwm = super().timing(r4005)
        return 2.0 ** (r4005 & 0xFF), pwm


class R4005OddCodesReadEven(Fun86Model):
    """R4005's low byte read with its bit 0 cleared: code 1 → 1 s, 3 → 4 s (0, the default 2 and 4 as they should)."""

    def timing(self, r4005):
        interval, _pwm = super().timing(r4005 & 0xFFFE)
        return interval, super().timing(r4005)[1]


class R4005HighOddCodesReadEven(Fun86Model):
    """R4005's high byte read with its bit 0 cleared: PWM code 1 → 1 s, 3 → 4 s (2 and 4 as they should)."""

    def timing(self, r4005):
        interval, _pwm = super().timing(r4005)
        return interval, super().timing(r4005 & 0xFEFF)[1]


class ErrLatchedUntilAnEnEdge(Fun86Model):
    """ERR, once set by a bad Sn/Zn, stays 1 while EN stays 1, whatever Sn/Zn become."""

    def scan(self, emu):
        bits = emu.memory.bits
        latched = getattr(self, "latched", set())
        self.latched = latched
        super().scan(emu)
        for inst in self.config.instances:
            if not bits[inst.en.kind][inst.en.index]:
                latched.discard(inst.name)
            elif bits[inst.err.kind][inst.err.index]:
                latched.add(inst.name)
            elif inst.name in latched:
                bits[inst.err.kind][inst.err.index] = 1


class HeaterLoopR4007LowByte(Fun86Model):
    """Only R4007's low byte taken as the heater-loop time (256 s → 0 s)."""

    def scan(self, emu):
        words = emu.memory.words["R"]
        saved = words[4007]
        words[4007] = saved & 0xFF
        try:
            super().scan(emu)
        finally:
            words[4007] = saved


class HeaterLoopTimerNotRestarted(Fun86Model):
    """An output dip under R4006 (PV still out of band) does not restart the heater-loop timer: it runs on from the
    first rise until PV comes into the band."""

    def track(self, st, idx, pv, high, normal, limit, now):
        super().track(st, idx, pv, high, normal, limit, now)
        first = self.__dict__.setdefault("first", {}).setdefault(id(st), {})
        for j, p in enumerate(np.arange(st.zn)[idx]):
            since = st.loop_since[p]
            if normal[j]:
                first.pop(p, None)
            elif since == since:
                st.loop_since[p] = first.setdefault(p, since)


class HeaterLoopIgnoresTheBand(Fun86Model):
    """The heater-loop timer runs on output ≥ R4006 % alone, PV in band or not."""

    def track(self, st, idx, pv, high, normal, limit, now):
        super().track(st, idx, pv, high, np.zeros(np.shape(pv), dtype=bool), limit, now)


class BitsCountFromPoint0(Fun86Model):
    """WR bits placed by the point's own number (bit p % 16 of word p // 16), not counted from Sn."""

    def bit_words(self, st, bits):
        if st.weights is None:
            word, bit = divmod(st.sn + np.arange(st.zn), 16)
            st.weights = np.stack((np.where(word == 0, 1 << bit, 0), np.where(word == 1, 1 << bit, 0)))
        return super().bit_words(st, bits)


class Variant:
    """Plugin for the inner run: the profile's emulator with ``model_class`` in place of FUN86."""

    def __init__(self, model_class: type[Fun86Model]) -> None:
        self.model_class = model_class

    def pytest_hil_make_emulator(self, profile, epoch):
        emulator = build_emulator(profile, epoch)
        good = emulator.model(Fun86Model)
        broken = self.model_class(good.config, good.temperature)
        broken.next_measurement = emulator.model(TemperatureModel).next_measurement
        replace_model(emulator, Fun86Model, broken)
        return emulator


CAUGHT_BY = {
    PrealarmAfter9Scans: ["test_prealarm_needs_10_consecutive_scans_on_a_bench[steady]"],
    PrealarmAfter11Scans: ["test_prealarm_needs_10_consecutive_scans_on_a_bench[steady]"],
    DipDoesNotResetTheCount: ["test_prealarm_needs_10_consecutive_scans_on_a_bench[dip]"],
    BandEdgesExclusive: ["test_normal_bit_exactly_at_sv_plus_minus_os[at-edge]"],
    LowPointsInSecondWord: ["test_normal_bit_positions_count_from_sn[first-instance]",
                            "test_prealarm_when_r4008_is_below_pv[first-instance]"],
    AlmIgnoresWarnings: ["test_alm_follows_a_warning_alone", "test_prealarm_when_r4008_is_below_pv"],
    HeaterLoopTimerTwiceAsFast: ["test_heater_loop_warning_after_r4007_seconds_and_not_before"],
    HeaterLoopTimerHalfSpeed: ["test_heater_loop_warning_after_r4007_seconds_and_not_before"],
    HeaterLoopIgnoresR4006: ["test_heater_loop_threshold_is_r4006[R4006-80-warns]"],
    HeaterLoopOnePercentEarly: ["test_heater_loop_warns_from_exactly_r4006"],
    HeaterLoopOnePercentLate: ["test_heater_loop_warns_from_exactly_r4006"],
    NoDerivativeAction: ["test_derivative_acts_on_a_pv_change_and_td_0_has_none"],
    TdInWholeMinutes: ["test_derivative_acts_on_a_pv_change_and_td_0_has_none"],
    NoErrForSnPlusZn33: ["test_err_exactly_for_invalid_sn_zn"],
    DisabledPointStillDriven: ["test_disabled_point_output_is_forced_off"],
    R4004Ignored: ["test_pvs_come_from_where_r4003_and_r4004_say", "test_prealarm_of_every_point_at_r4008"],
    R4004DBankRejected: ["test_pvs_come_from_where_r4003_and_r4004_say"],
    R4004UpperEdgesRejected: ["test_pvs_come_from_where_r4003_and_r4004_say"],
    R4004PastTheEndTaken: ["test_pvs_come_from_where_r4003_and_r4004_say"],
    R4003KeyIgnored: ["test_pvs_come_from_where_r4003_and_r4004_say"],
    BandComparedUnsigned: ["test_normal_bits_of_every_point_at_both_edges_and_alm"],
    AlmIgnoresTheSecondWords: ["test_normal_bits_of_every_point_at_both_edges_and_alm",
                               "test_prealarm_of_every_point_at_r4008"],
    PrealarmOnlyAboveR4008: ["test_prealarm_of_every_point_at_r4008",
                             "test_prealarm_needs_10_consecutive_scans_on_a_bench[at-r4008]"],
    PrealarmLimitSigned: ["test_prealarm_of_every_point_at_r4008"],
    PrealarmPvUnsigned: ["test_prealarm_of_every_point_at_r4008"],
    R4013Ignored: ["test_disabled_point_output_is_forced_off"],
    ActsBeforeMeasured: ["test_first_execution_loads_kc_ki_td_110_17_50"],
    CoolingHeats: ["test_output_on_below_sv_and_off_far_above"],
    R4005AppliedAtOnce: ["test_a_new_pid_interval_waits_for_en_to_go_0_and_back_to_1"],
    PwmInverted: ["test_a_new_pid_interval_waits_for_en_to_go_0_and_back_to_1"],
    OutputClampedAt10000: ["test_disabled_point_output_is_forced_off"],
    KiZeroStillIntegrates: ["test_a_new_pid_interval_waits_for_en_to_go_0_and_back_to_1"],
    Zn32Refused: ["test_err_exactly_for_invalid_sn_zn"],
    PwmPeriodFromTheLowByte: ["test_a_new_pid_interval_waits_for_en_to_go_0_and_back_to_1"],
    R4005NotClamped: ["test_each_r4005_code_gives_its_interval_and_pwm_period"],
    R4005ClampedInTheLowByteOnly: ["test_each_r4005_code_gives_its_interval_and_pwm_period"],
    R4005ClampedInTheHighByteOnly: ["test_each_r4005_code_gives_its_interval_and_pwm_period"],
    R4005OddCodesReadEven: ["test_each_r4005_code_gives_its_interval_and_pwm_period[R4005-0301H]",
                            "test_each_r4005_code_gives_its_interval_and_pwm_period[R4005-0403H]"],
    R4005HighOddCodesReadEven: ["test_each_r4005_code_gives_its_interval_and_pwm_period[R4005-0104H]",
                                "test_each_r4005_code_gives_its_interval_and_pwm_period[R4005-0301H]"],
    ErrLatchedUntilAnEnEdge: ["test_err_clears_when_sn_zn_become_valid_with_en_held"],
    HeaterLoopR4007LowByte: ["test_heater_loop_warning_after_r4007_seconds_and_not_before[R4007-256]"],
    HeaterLoopTimerNotRestarted: ["test_heater_loop_timer_restarts_when_the_output_dips_below_r4006"],
    HeaterLoopIgnoresTheBand: ["test_heater_loop_stays_off_with_pv_in_band"],
    BitsCountFromPoint0: ["test_normal_bit_positions_count_from_sn[second-instance]",
                          "test_prealarm_when_r4008_is_below_pv[second-instance]"],
    SecondWordsKeepFourBits: ["test_normal_bits_of_every_point_at_both_edges_and_alm",
                              "test_prealarm_of_every_point_at_r4008"],
}


def _failed(result):
    return {r.nodeid.split("::")[-1] for r in result.getreports("pytest_runtest_logreport")
            if r.when == "call" and r.failed}


@pytest.mark.parametrize("variant", list(CAUGHT_BY), ids=lambda v: v.__name__)
def test_the_pid_suites_catch_a_broken_fun86(pytester, variant):
    # only the tests that must catch it run (the rest of the suites is the correct FUN86's run below): CI time
    only = ("-k", " or ".join(CAUGHT_BY[variant]))
    result = pytester.inline_run(*SUITES, *INNER, *only, "--bench", str(EMULATOR_BENCH), plugins=[Variant(variant)])
    failed = _failed(result)
    for name in CAUGHT_BY[variant]:
        assert any(f == name or f.startswith(name + "[") for f in failed), (
            f"{variant.__name__} passed {name}; failed only: {sorted(failed)}")


def test_the_correct_fun86_passes_through_the_same_hook(pytester):
    result = pytester.inline_run(*SUITES, *INNER, "--bench", str(EMULATOR_BENCH), plugins=[Variant(Fun86Model)])
    result.assertoutcome(passed=SUITE_TESTS)
