"""The RTC end to end on the emulator: RtcModel behind LocalTransport, driven through plc.rtc.

Expected values are stated literally from the manual (fbs-rtc.md); [our choice] behaviours are marked.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from types import SimpleNamespace

import pytest

from hil.core.timebase import EmulatorTimebase
from hil.families.fbs import registers as reg
from hil.families.fbs.d4054 import rate_for_code
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.device.rtc import RtcError, RtcFlags
from hil.families.fbs.rtc_time import RtcTime
from hil.families.fbs.sim.models.rtc import RtcModel
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.transport.local import LocalTransport

START = dt.datetime(2024, 3, 10, 8, 0, 0)
FINE_STEP = 0.087890625  # s/day: the finest D4054 step; drift results must resolve well below it


def make_rig(chip: int = 3, ppm: float = 0.0, start: dt.datetime = START,
             model_cls: type[RtcModel] = RtcModel) -> SimpleNamespace:
    model = model_cls(chip=chip, crystal_ppm=ppm, start=start)
    emu = Emulator(models=[model])
    plc = FbsPlc(LocalTransport(emu), EmulatorTimebase(emu, start))
    return SimpleNamespace(emu=emu, plc=plc, rtc=plc.rtc, model=model)


@pytest.fixture
def rig() -> SimpleNamespace:
    return make_rig()


def rt(*args: int) -> RtcTime:
    """RtcTime from (Y, M, D, h, m, s) with the weekday of the date."""
    return RtcTime.from_datetime(dt.datetime(*args))


# -- read-out and set ------------------------------------------------------------------------------------------
def test_power_on_shows_the_start_time(rig: SimpleNamespace) -> None:
    assert rig.rtc.read() == rt(2024, 3, 10, 8, 0, 0)
    assert rig.rtc.read().weekday == 0  # 10 Mar 2024 is a Sunday [our choice: 0 = Sunday]


@pytest.mark.parametrize("when", [
    dt.datetime(2024, 2, 29, 12, 34, 56),  # leap day
    dt.datetime(2000, 1, 1, 0, 0, 0),
    dt.datetime(2099, 12, 31, 23, 59, 59),
    dt.datetime(2037, 7, 4, 13, 45, 0),
])
def test_set_then_read_round_trip(rig: SimpleNamespace, when: dt.datetime) -> None:
    result = rig.rtc.set(when)
    assert result.accepted and result.problems == ()
    assert rig.rtc.read() == RtcTime.from_datetime(when)
    assert rig.rtc.read_hour_minute() == when.hour << 8 | when.minute
    assert rig.rtc.read_flags() == RtcFlags(hold=False, adjust_30s=False, installed=True, set_error=False)


@pytest.mark.parametrize(("when", "after"), [
    # the two-digit year wraps; the weekday counts on, Thursday → Friday (1 Jan 2000 was a Saturday): RTC-RUN-3
    (dt.datetime(2099, 12, 31, 23, 59, 59), dataclasses.replace(rt(2000, 1, 1, 0, 0, 0), weekday=5)),
    (dt.datetime(2024, 2, 28, 23, 59, 59), rt(2024, 2, 29, 0, 0, 0)),
    (dt.datetime(2023, 2, 28, 23, 59, 59), rt(2023, 3, 1, 0, 0, 0)),
    (dt.datetime(2024, 2, 29, 23, 59, 59), rt(2024, 3, 1, 0, 0, 0)),
])
def test_clock_rolls_over(rig: SimpleNamespace, when: dt.datetime, after: RtcTime) -> None:
    assert rig.rtc.set(when)
    rig.plc.time.wait(1.0)
    assert rig.rtc.read() == after


def test_r4135_is_hour_high_minute_low(rig: SimpleNamespace) -> None:
    rig.rtc.set(dt.datetime(2024, 5, 1, 13, 45, 10))
    assert rig.plc.io.read(reg.RTC_HOUR_MINUTE) == 0x0D2D


def test_weekday_written_is_not_checked_and_the_chip_counts_on_from_it(rig: SimpleNamespace) -> None:
    wrong = dataclasses.replace(rt(2024, 2, 29, 23, 59, 59), weekday=0)  # a Thursday written as Sunday
    assert rig.rtc.set(wrong).accepted  # [our choice] weekday range-checked only
    assert rig.rtc.read().weekday == 0  # the chip's own counter: never computed from the date
    rig.plc.time.wait(1.0)
    assert rig.rtc.read().weekday == 1  # one day on


def test_weekday_counter_survives_a_new_d4054_code(rig: SimpleNamespace) -> None:
    """A new code re-anchors the chip: its weekday counter is carried over, not recomputed from the date."""
    rig.rtc.set(dataclasses.replace(rt(2024, 2, 29, 10, 0, 0), weekday=2))
    rig.rtc.rate_code = 0x56E5
    rig.plc.settle()
    assert rig.rtc.read().weekday == 2


def test_registers_freeze_while_m1952_is_set_and_the_chip_keeps_counting(rig: SimpleNamespace) -> None:
    io = rig.plc.io
    rig.rtc.set(dt.datetime(2024, 6, 1, 10, 0, 0))
    io.write(reg.RTC_HOLD, 1)
    frozen = rig.rtc.read()
    rig.plc.time.wait(5.0)
    assert rig.rtc.read() == frozen
    io.write_words(reg.RTC_SECOND, [60, 0, 0, 0, 0, 0, 0])  # the harness's values stay put while held
    rig.plc.time.wait(5.0)
    assert io.read_words(reg.RTC_SECOND, 7) == [60, 0, 0, 0, 0, 0, 0]
    # Releasing with invalid values sets nothing: read-out resumes on the chip, which never stopped.
    io.write(reg.RTC_HOLD, 0)
    rig.plc.settle()
    assert rig.rtc.read_flags().set_error
    assert rig.rtc.read() == rt(2024, 6, 1, 10, 0, 10)  # [our choice] the chip counts while M1952 = 1


INVALID = [
    ("second", {"second": 60}),
    ("minute", {"minute": 60}),
    ("hour", {"hour": 24}),
    ("day", {"day": 0}),
    ("day", {"month": 4, "day": 31}),  # 31 April
    ("day", {"year": 23, "month": 2, "day": 29}),  # 29 Feb 2023
    ("month", {"month": 0}),
    ("month", {"month": 13}),
    ("year", {"year": 100}),
    ("weekday", {"weekday": 7}),
]


@pytest.mark.parametrize(("field", "changes"), INVALID, ids=[f"{f}-{'-'.join(map(str, c.values()))}"
                                                              for f, c in INVALID])
def test_invalid_set_is_refused_and_the_clock_keeps_its_time(rig: SimpleNamespace, field: str,
                                                             changes: dict) -> None:
    assert rig.rtc.set(dt.datetime(2024, 4, 30, 9, 15, 0))
    rig.plc.time.wait(2.0)
    bad = dataclasses.replace(rt(2024, 4, 10, 12, 0, 0), **changes)
    result = rig.rtc.set(bad)
    assert result.refused and field in result.problems
    assert rig.rtc.read_flags().set_error  # M1955
    rig.plc.time.wait(3.0)
    assert rig.rtc.read() == rt(2024, 4, 30, 9, 15, 5)  # still running on its previous time
    # a valid set after a refused one clears M1955 [our choice]
    assert rig.rtc.set(dt.datetime(2024, 4, 30, 9, 0, 0)).accepted
    assert not rig.rtc.read_flags().set_error
    assert rig.rtc.read() == rt(2024, 4, 30, 9, 0, 0)


# -- ±30 s ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("before", "after"), [
    (dt.datetime(2024, 5, 1, 10, 20, 0), rt(2024, 5, 1, 10, 20, 0)),
    (dt.datetime(2024, 5, 1, 10, 20, 15), rt(2024, 5, 1, 10, 20, 0)),
    (dt.datetime(2024, 5, 1, 10, 20, 29), rt(2024, 5, 1, 10, 20, 0)),
    (dt.datetime(2024, 5, 1, 10, 20, 30), rt(2024, 5, 1, 10, 21, 0)),
    (dt.datetime(2024, 5, 1, 10, 20, 59), rt(2024, 5, 1, 10, 21, 0)),
    # [our choice] the minute carries like a real clock
    (dt.datetime(2024, 5, 1, 10, 59, 45), rt(2024, 5, 1, 11, 0, 0)),
    (dt.datetime(2024, 5, 31, 23, 59, 45), rt(2024, 6, 1, 0, 0, 0)),
    (dt.datetime(2024, 2, 28, 23, 59, 31), rt(2024, 2, 29, 0, 0, 0)),
    (dt.datetime(2023, 12, 31, 23, 59, 30), rt(2024, 1, 1, 0, 0, 0)),
    (dt.datetime(2099, 12, 31, 23, 59, 30), dataclasses.replace(rt(2000, 1, 1, 0, 0, 0), weekday=5)),  # counted on
])
def test_adjust_30s(rig: SimpleNamespace, before: dt.datetime, after: RtcTime) -> None:
    assert rig.rtc.set(before)
    rig.rtc.adjust_30s()
    got = rig.rtc.read()
    assert got == after
    assert got.weekday == after.weekday  # the weekday counter advances by one with the date
    assert not rig.rtc.read_flags().adjust_30s


def test_adjust_30s_fires_on_the_rising_edge_only(rig: SimpleNamespace) -> None:
    rig.rtc.set(dt.datetime(2024, 5, 1, 10, 20, 40))
    rig.plc.io.write(reg.RTC_ADJUST_30S, 1)
    rig.plc.settle()
    assert rig.rtc.read() == rt(2024, 5, 1, 10, 21, 0)
    rig.plc.time.wait(40.0)  # holding M1953 at 1 does nothing more
    assert rig.rtc.read() == rt(2024, 5, 1, 10, 21, 40)


def test_adjust_30s_fires_when_m1953_was_left_at_1(rig: SimpleNamespace) -> None:
    """The procedure reads M1953 first, settled; left at 1 by someone else, it is put to 0 and held a scan before
    the 1 — and when it reads 0, no write of 0 goes out."""
    rig.plc.io.write(reg.RTC_ADJUST_30S, 1)
    rig.plc.settle()
    assert rig.rtc.set(dt.datetime(2024, 5, 1, 10, 20, 40))
    rig.rtc.adjust_30s()
    assert rig.rtc.read() == rt(2024, 5, 1, 10, 21, 0)
    assert not rig.rtc.read_flags().adjust_30s
    assert rig.rtc.set(dt.datetime(2024, 5, 1, 10, 20, 10))
    before = rig.plc.io.requests
    rig.rtc.adjust_30s()
    # the read of M1953 (the set's read-back already spanned a scan after its last write: port 0's rule, no status
    # request), the 1, a scan, the 0, a scan
    assert rig.plc.io.requests - before == 5
    assert rig.rtc.read() == rt(2024, 5, 1, 10, 20, 0)


# -- chip identity, D4054 ----------------------------------------------------------------------------------------
@pytest.mark.parametrize(("chip", "name"), [(0, "none"), (1, "HT1381"), (2, "ISL1208"), (3, "S-35390A")])
def test_m1954_matches_d4053(chip: int, name: str) -> None:
    rig = make_rig(chip=chip)
    assert int(rig.rtc.chip) == chip and rig.rtc.chip.name == name
    assert rig.rtc.installed == (chip != 0)
    rig.plc.io.write(reg.RTC_CHIP, 7)  # D4053 is read-only for users: the PLC puts it back
    rig.plc.settle()
    assert int(rig.rtc.chip) == chip


def test_without_a_chip_the_registers_are_not_updated() -> None:
    rig = make_rig(chip=0)
    rig.plc.time.wait(10.0)
    assert rig.plc.io.read_words(reg.RTC_SECOND, 8) == [0] * 8


@pytest.mark.parametrize("code", [0x56E5, 0x5603, 0x0000, 0x1234, 0xFFFF])
def test_d4054_reads_back(rig: SimpleNamespace, code: int) -> None:
    rig.rtc.rate_code = code
    rig.plc.settle()
    assert rig.rtc.rate_code == code


def test_rate_code_applies_continuously_from_the_moment_it_is_written(rig: SimpleNamespace) -> None:
    rig.rtc.set(dt.datetime(2024, 6, 1, 0, 0, 0))
    rig.plc.time.wait(43200.0)
    assert rig.rtc.read() == rt(2024, 6, 1, 12, 0, 0)  # no drift, no correction
    rig.rtc.rate_code = 0x56FC  # coarse +63: slows the chip by 16.611 s/day
    rig.plc.time.wait(43200.0)
    assert rig.rtc.read() == rt(2024, 6, 1, 23, 59, 51)  # 8.31 s lost in the half day


@pytest.mark.parametrize("chip", [1, 2])
def test_other_chips_ignore_d4054(chip: int) -> None:
    rig = make_rig(chip=chip)
    rig.rtc.rate_code = 0x56FC
    rig.plc.time.wait(86400.0)
    assert rig.rtc.read() == RtcTime.from_datetime(START + dt.timedelta(days=1))


@pytest.mark.parametrize("code", [0x1234, 0xFFFF, 0x0056])
def test_codes_that_are_not_56xx_apply_nothing(rig: SimpleNamespace, code: int) -> None:
    rig.rtc.rate_code = code  # [our choice] the manual is silent
    rig.plc.time.wait(86400.0)
    assert rig.rtc.read() == RtcTime.from_datetime(START + dt.timedelta(days=1))


# -- drift ------------------------------------------------------------------------------------------------------
def _jumped_not_scanned(emu: Emulator) -> None:
    """Virtual time was jumped, not stepped scan by scan: under a thousandth of the scans a PLC would have run in it
    were run (counted, not timed: how fast a simulated day is, is a benchmark's figure,
    benchmarks/bench_host_time.py)."""
    stepped = round(emu.now / emu.scan_time)
    assert emu.scans < stepped / 1000, f"{emu.scans} scans run for {emu.now:.0f} virtual seconds"


def test_a_simulated_day_is_jumped_not_scanned() -> None:
    rig = make_rig(ppm=39)
    rig.plc.time.wait(86400.0)
    after = rig.rtc.read()
    assert after == RtcTime.from_datetime(START + dt.timedelta(days=1, seconds=3))  # +3.37 s
    _jumped_not_scanned(rig.emu)


def test_drift_measure_and_compensate() -> None:
    rig = make_rig(ppm=39)  # 39 ppm fast = 3.3696 s/day
    before = rig.rtc.drift.measure(86400.0)
    code = rig.rtc.drift.compensate(before.s_per_day)
    after = rig.rtc.drift.measure(86400.0)
    print(f"\ndrift +39 ppm: measured {before.s_per_day:+.4f} s/day (true +3.3696, resolution "
          f"{before.resolution:.4f}); code {code:04X}H ({rate_for_code(code).s_per_day:+.4f}); residual "
          f"{after.s_per_day:+.4f} s/day (true {3.3696 - rate_for_code(code).s_per_day:+.4f}); "
          f"{rig.emu.scans} scans for two simulated days")
    _jumped_not_scanned(rig.emu)  # two days of polling the clock's seconds, on virtual time
    assert before.s_per_day == pytest.approx(39e-6 * 86400, abs=0.03)
    assert before.resolution < FINE_STEP / 2
    assert 86390 < before.reference_elapsed < 86401
    assert len(before.samples) == 3 + 8 + 3 and before.samples[0] == (0.0, 0.0)  # start, checkpoints, end
    checkpoints = [y for _, y in before.samples[3:-3]]
    assert checkpoints == sorted(checkpoints)  # a clock fast by 39 ppm gains ~0.42 s between checkpoints
    assert before.samples[-1][1] == pytest.approx(3.37, abs=0.05)  # PLC − reference after a day
    assert code == 0x56E5  # the manual's row for 3.38
    assert rig.rtc.rate_code == 0x56E5
    assert abs(after.s_per_day) < FINE_STEP


def test_drift_slow_clock_is_corrected_too() -> None:
    rig = make_rig(ppm=-65)  # 5.616 s/day slow
    before = rig.rtc.drift.measure(86400.0)
    assert before.s_per_day == pytest.approx(-5.616, abs=0.03)
    assert rig.rtc.drift.compensate(before.s_per_day) == 0x5603  # the manual's row for −5.62
    assert abs(rig.rtc.drift.measure(86400.0).s_per_day) < FINE_STEP


def test_drift_on_a_stopped_clock_raises() -> None:
    rig = make_rig(chip=0)
    with pytest.raises(RtcError, match="not running"):
        rig.rtc.drift.measure(100.0)


def test_sync_to_host_aligns_the_second_boundaries() -> None:
    rig = make_rig(start=dt.datetime(2030, 1, 1))
    rig.plc.time.wait(12.345)  # host time now has a fraction of a second
    assert rig.rtc.sync_to_host().accepted
    for pause in (0.0, 0.5, 0.3, 0.4, 100.27):
        rig.plc.time.wait(pause)
        host = rig.plc.time.calendar()
        assert rig.rtc.read() == RtcTime.from_datetime(host)


# -- the seams: deliberately broken PLCs are caught by the same checks -------------------------------------------
class ForgetsApril(RtcModel):
    def validate(self, t: RtcTime) -> list[str]:
        return [f for f in t.validate() if not (f == "day" and t.month == 4 and t.day == 31)]


class ManualSignWrong(RtcModel):
    def correction_rate(self, code: int) -> float:
        return -super().correction_rate(code)


def test_broken_validate_is_visible() -> None:
    rig = make_rig(model_cls=ForgetsApril)
    result = rig.rtc.set(RtcTime(second=0, minute=0, hour=0, day=31, month=4, year=24, weekday=3))
    assert result.accepted and result.problems == ("day",)  # a suite comparing the two finds the defect
    assert rig.rtc.read() == rt(2024, 5, 1, 0, 0, 0)  # the emulator survives: 31 April rolls into May


def test_wrong_correction_sign_doubles_the_error() -> None:
    rig = make_rig(ppm=39, model_cls=ManualSignWrong)
    first = rig.rtc.drift.measure(86400.0)
    rig.rtc.drift.compensate(first.s_per_day)
    assert rig.rtc.drift.measure(86400.0).s_per_day == pytest.approx(2 * first.s_per_day, abs=0.15)
