"""D4054 drift compensation of the S-35390A (D4053 = 3), FBs manual ch. 15 and its Table 1.

Procedure from the manual: measure the clock's error in s/day, look the code up in Table 1, write it to D4054.
The chip then corrects in steps of 0.088 s/day (fine mode), so a compensated clock must be within one fine step.
"""

from __future__ import annotations

import pytest

from hil.families.fbs.d4054 import code_for_rate, rate_for_code

FINE_STEP = 0.088  # s/day, the manual's fine-mode resolution
# the clock lane: only the RTC suites touch the clock and D4054 (hil run --lanes)
pytestmark = pytest.mark.lane("clock")
#: One code of Table 1 per kind of row, each end of each kind: coarse and fine mode, both signs, the fastest and
#: slowest of each, no correction, the misprinted rows' codes and the codes consistent with their rates.
TABLE_1_CODES = {
    0x56FC: "+16.61 s/day: coarse, the largest",
    0x56A8: "+5.56: coarse, the smallest positive",
    0x56FD: "+5.54: fine, the largest",
    0x56E5: "+3.38: fine, the manual's worked example",
    0x5681: "+0.09: fine, the smallest positive",
    0x0000: "0: no correction",
    0x56FF: "-0.09: fine, the smallest negative",
    0x5603: "-5.62: fine, the most negative, the manual's worked example",
    0x5656: "-5.83: coarse, the smallest negative",
    0x5602: "-16.88: coarse, the most negative",
    0x5618: "+2.05 as printed (a misprint: 5618H is also the +6.36 row)",
    0x5619: "+2.05: the code consistent with its rate",
    0x56C8: "+1.63 as printed (a misprint)",
    0x56C9: "+1.63: the code consistent with its rate",
}


@pytest.fixture
def s35390a(bench):
    reason = bench.cannot_reach("D4054")
    if reason:
        pytest.skip(f"D4054 tests need D4054: {reason}")
    chip = bench.plc.io.read("D4053")
    if chip != 3:
        pytest.skip(f"D4054 applies only to the S-35390A (D4053 = 3); this PLC reports D4053 = {chip}")
    return bench.plc.rtc


@pytest.mark.spec("RTC-DRIFT-7", "RTC-DRIFT-3")
def test_d4054_write_read_back_of_every_table_1_code(s35390a, io):
    """Every kind of Table 1 code, written and read back one after the other."""
    wrong = []
    for code, row in TABLE_1_CODES.items():
        io.write("D4054", code)
        if (got := io.read("D4054")) != code:
            wrong.append(f"{code:04X}H ({row}) read back as {got:04X}H")
    assert not wrong, ", ".join(wrong)


@pytest.mark.spec("RTC-DRIFT-3")
def test_table_codes_of_the_manuals_worked_examples():
    assert code_for_rate(3.38) == 0x56E5  # "runs fast by 3.38 s/day"
    assert code_for_rate(-5.62) == 0x5603  # "runs slow by 5.62 s/day"


def _drift_max_s(profile) -> float:
    rtc = profile.rtc
    return (rtc.drift_max_hours if rtc is not None else 12.0) * 3600


def _planned(profile) -> float:
    """Two measurements of at most [rtc] drift_max_hours each, plus the bracket probes and the set-up."""
    return 2 * _drift_max_s(profile) + 120


@pytest.mark.slow
@pytest.mark.bench_time(_planned, reason="two drift measurements of up to [rtc] drift_max_hours")
@pytest.mark.spec("RTC-DRIFT-1", "RTC-DRIFT-2", "RTC-DRIFT-4")
@pytest.mark.measures("drift_uncompensated", unit="s/day")
@pytest.mark.measures("drift_residual", unit="s/day", low=-FINE_STEP, high=FINE_STEP)
def test_drift_measured_compensated_and_remeasured(bench, s35390a, io, measure, report):
    """No pass without evidence: each measurement goes on until its resolution is below the manual's fine step
    (up to the bench's [rtc] drift_max_hours); one that cannot get there fails the test as inconclusive.  The
    limit is the fine step itself, never widened by the measurement's resolution."""
    max_s = _drift_max_s(bench.profile)
    if max_s <= 0:
        pytest.skip("this bench does not measure drift ([rtc] drift_max_hours = 0); give it the hours a "
                    "measurement to 0.088 s/day takes here")
    io.write("D4054", 0x0000)
    before = s35390a.drift.measure_until(FINE_STEP, max_s)
    report.attach_drift(before, "drift_uncompensated", title=f"uncompensated: {before.s_per_day:+.3f} s/day")
    measure("drift_uncompensated", before.s_per_day)  # evidence only: the chip's own error
    _conclusive(before, max_s, "uncompensated")
    code = s35390a.drift.compensate(before.s_per_day)
    assert io.read("D4054") == code == code_for_rate(before.s_per_day)
    after = s35390a.drift.measure_until(FINE_STEP, max_s)
    report.attach_drift(after, "drift_residual", title=f"D4054 = {code:04X}H: residual {after.s_per_day:+.3f} s/day")
    measure("drift_residual", after.s_per_day,
            note=f"drift {before.s_per_day:+.3f} s/day, D4054 = {code:04X}H; a residual near twice the drift "
                 f"means the correction's sign is inverted; resolution {after.resolution:.3f} s/day")
    _conclusive(after, max_s, "residual")
    assert abs(after.s_per_day) <= FINE_STEP, (
        f"drift {before.s_per_day:+.3f} s/day, D4054 = {code:04X}H, residual {after.s_per_day:+.3f} s/day "
        f"(limit ±{FINE_STEP}); a residual near twice the drift means the correction's sign is inverted")


def _conclusive(result, max_s: float, what: str, needed: float = FINE_STEP,
                needed_is: str = "the manual's fine step") -> None:
    if not result.resolution < needed:
        pytest.fail(f"inconclusive: the {what} drift measurement's resolution is {result.resolution:.3f} s/day "
                    f"after {result.reference_elapsed / 3600:.2f} h, not below {needed_is} {needed} "
                    f"s/day; measure longer ([rtc] drift_max_hours, now {max_s / 3600:g} h) or poll faster",
                    pytrace=False)


#: Table 1's largest code: 56FCH for a clock fast by 16.61 s/day, i.e. a correction 16.6113 s/day slower
LARGEST_CODE = 0x56FC
LARGEST_CORRECTION = -rate_for_code(LARGEST_CODE).s_per_day
#: each measurement's resolution (s/day): ample to tell a 16.6 s/day correction from none or from its opposite
DIRECTION_RESOLUTION = 4.0


@pytest.mark.slow
@pytest.mark.bench_time(_planned, reason="two drift measurements of up to [rtc] drift_max_hours")
@pytest.mark.spec("RTC-DRIFT-1", "RTC-DRIFT-3", "RTC-DRIFT-4")
@pytest.mark.measures("d4054_largest_correction", unit="s/day")  # its limits: the resolutions the run reached
def test_d4054_largest_code_slows_the_clock_by_table_1s_amount(bench, s35390a, io, measure):
    """The direction and size of D4054's correction, in a fraction of the fine-step test's bench time: the clock's
    rate measured at D4054 = 0 and at 56FCH (Table 1: a clock fast by 16.61 s/day) must differ by −16.61 s/day
    within the two measurements' resolutions (each below 4 s/day).  A PLC that applies the code with the wrong
    sign (+16.6) or not at all (0) is outside that by far."""
    max_s = _drift_max_s(bench.profile)
    if max_s <= 0:
        pytest.skip("this bench does not measure drift ([rtc] drift_max_hours = 0); give it the hours a "
                    "measurement to 4 s/day takes here")
    io.write("D4054", 0x0000)
    plain = s35390a.drift.measure_until(DIRECTION_RESOLUTION, max_s)
    _conclusive(plain, max_s, "D4054 = 0", DIRECTION_RESOLUTION, "the direction check's")
    io.write("D4054", LARGEST_CODE)
    corrected = s35390a.drift.measure_until(DIRECTION_RESOLUTION, max_s)
    _conclusive(corrected, max_s, f"D4054 = {LARGEST_CODE:04X}H", DIRECTION_RESOLUTION, "the direction check's")
    change = corrected.s_per_day - plain.s_per_day
    within = plain.resolution + corrected.resolution
    measure("d4054_largest_correction", change, low=LARGEST_CORRECTION - within,
            high=LARGEST_CORRECTION + within,
            note=f"{plain.s_per_day:+.3f} s/day at D4054 = 0, {corrected.s_per_day:+.3f} at {LARGEST_CODE:04X}H")
    assert abs(change - LARGEST_CORRECTION) <= within, (
        f"D4054 = {LARGEST_CODE:04X}H changed the clock's rate by {change:+.3f} s/day; Table 1: "
        f"{LARGEST_CORRECTION:+.3f} s/day (± {within:.3f}, the measurements' resolutions); "
        f"{'the correction has the wrong sign' if change > 0 else 'the code is not applied as the table says'}")
