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
    """Every kind of Table 1 code, written and read back one after the other.  Each differs from the one before it,
    so each read-back shows a write: where D4054 already held the first code, that one goes last."""
    codes = list(TABLE_1_CODES.items())
    if io.read("D4054") == codes[0][0]:
        codes = codes[1:] + codes[:1]
    wrong = []
    for code, row in codes:
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


def _planned(measurements: int):
    """The bench time of ``measurements`` drift measurements of at most [rtc] drift_max_hours each, plus the bracket
    probes and the set-up."""
    return lambda profile: measurements * (_drift_max_s(profile) + 60)


@pytest.mark.slow
@pytest.mark.bench_time(_planned(2), reason="two drift measurements of up to [rtc] drift_max_hours")
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


#: Table 1's largest code of each sign and the rate change it makes (s/day, the manual's sign: the code for a clock
#: fast by r slows it by r): 56FCH for a clock fast by 16.61 s/day, 5602H for one slow by 16.88 s/day
EXTREME_CODES = {code: -rate_for_code(code).s_per_day for code in (0x56FC, 0x5602)}
#: the code kept in force across a set of the clock
KEPT_CODE = 0x5602
#: each measurement's resolution (s/day): ample to tell a 16.6 s/day correction from none or from its opposite
DIRECTION_RESOLUTION = 4.0


def _direction_max_s(bench) -> float:
    """[rtc] drift_max_hours in bench seconds; skip (before anything is written) where the bench measures no drift."""
    max_s = _drift_max_s(bench.profile)
    if max_s <= 0:
        pytest.skip("this bench does not measure drift ([rtc] drift_max_hours = 0); give it the hours a "
                    "measurement to 4 s/day takes here")
    return max_s


def _direction_measurement(s35390a, max_s: float, what: str):
    """The clock's rate as it runs now, to the direction checks' resolution (or the test fails as inconclusive)."""
    result = s35390a.drift.measure_until(DIRECTION_RESOLUTION, max_s)
    _conclusive(result, max_s, what, DIRECTION_RESOLUTION, "the direction check's")
    return result


#: what a direction check's rate change outside its limits usually means
WRONG_DIRECTION = "a change of the opposite sign means the correction's sign is inverted, none that it is not applied"


def _rate_change(measure, name: str, before, after, expected: float, what: str, meaning: str) -> None:
    """The rate change from ``before`` to ``after`` (``what`` made it) as measurement ``name``: ``expected`` s/day
    within the two measurements' resolutions (measure() fails the test at once outside them, saying ``meaning``)."""
    within = before.resolution + after.resolution
    measure(name, after.s_per_day - before.s_per_day, low=expected - within, high=expected + within,
            note=f"{what}: {before.s_per_day:+.3f} s/day before, {after.s_per_day:+.3f} after; expected "
                 f"{expected:+.3f} ± {within:.3f} (the resolutions): {meaning}")


@pytest.mark.slow
@pytest.mark.bench_time(_planned(3), reason="three drift measurements of up to [rtc] drift_max_hours")
@pytest.mark.spec("RTC-DRIFT-1", "RTC-DRIFT-3", "RTC-DRIFT-4")
@pytest.mark.measures("d4054_largest_correction", unit="s/day")  # its limits: the resolutions the run reached
@pytest.mark.measures("d4054_most_negative_correction", unit="s/day")
def test_d4054_largest_codes_of_both_signs_change_the_rate_by_table_1s_amount(bench, s35390a, io, measure):
    """The direction and size of D4054's correction for each sign, in a fraction of the fine-step test's bench time:
    the clock's rate measured at D4054 = 0, at 56FCH (Table 1: a clock fast by 16.61 s/day) and at 5602H (slow by
    16.88 s/day) must differ by −16.61 and +16.88 s/day within the measurements' resolutions (each below 4 s/day).
    A PLC that applies a code with the wrong sign (for either sign) or not at all is outside that by far."""
    max_s = _direction_max_s(bench)
    io.write("D4054", 0x0000)
    plain = _direction_measurement(s35390a, max_s, "D4054 = 0")
    for (code, expected), name in zip(EXTREME_CODES.items(), ("d4054_largest_correction",
                                                              "d4054_most_negative_correction")):
        io.write("D4054", code)
        corrected = _direction_measurement(s35390a, max_s, f"D4054 = {code:04X}H")
        _rate_change(measure, name, plain, corrected, expected, f"D4054 = 0 → {code:04X}H", WRONG_DIRECTION)


@pytest.mark.slow
@pytest.mark.bench_time(_planned(2), reason="two drift measurements of up to [rtc] drift_max_hours")
@pytest.mark.spec("RTC-DRIFT-10", "RTC-DRIFT-1")
@pytest.mark.measures("d4054_rate_change_at_a_set", unit="s/day")  # its limits: the resolutions the run reached
def test_d4054_correction_stays_in_force_across_a_set_of_the_clock(bench, s35390a, io, measure):
    """A set loads the time, not the rate: with 5602H in D4054 (Table 1: a clock slow by 16.88 s/day) the rate
    measured after a set of the clock must be the rate measured before it, within the two measurements'
    resolutions (each below 4 s/day).  A PLC that drops the correction at a set changes it by −16.88 s/day."""
    max_s = _direction_max_s(bench)
    io.write("D4054", KEPT_CODE)
    before = _direction_measurement(s35390a, max_s, f"D4054 = {KEPT_CODE:04X}H")
    assert s35390a.set(s35390a.read().to_datetime()).accepted  # the clock set to the time it shows
    after = _direction_measurement(s35390a, max_s, f"D4054 = {KEPT_CODE:04X}H after a set")  # begun after it
    _rate_change(measure, "d4054_rate_change_at_a_set", before, after, 0.0,
                 f"a set of the clock with D4054 = {KEPT_CODE:04X}H in force",
                 f"a change near {-EXTREME_CODES[KEPT_CODE]:+.2f} s/day means the set dropped the correction")
