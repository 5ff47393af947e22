"""D4054 drift compensation of the S-35390A (D4053 = 3), FBs manual ch. 15 and its Table 1.

Procedure from the manual: measure the clock's error in s/day, look the code up in Table 1, write it to D4054.
The chip then corrects in steps of 0.088 s/day (fine mode), so a compensated clock must be within one fine step.
"""

from __future__ import annotations

import pytest

from hil.families.fbs.d4054 import code_for_rate

FINE_STEP = 0.088  # s/day, the manual's fine-mode resolution


@pytest.fixture
def s35390a(bench):
    reason = bench.cannot_reach("D4054")
    if reason:
        pytest.skip(f"D4054 tests need D4054: {reason}")
    chip = bench.plc.io.read("D4053")
    if chip != 3:
        pytest.skip(f"D4054 applies only to the S-35390A (D4053 = 3); this PLC reports D4053 = {chip}")
    return bench.plc.rtc


@pytest.mark.parametrize("code", [0x56E5, 0x5603, 0x56FC, 0x5602, 0x0000])
def test_d4054_write_read_back(s35390a, io, code):
    io.write("D4054", code)
    assert io.read("D4054") == code


def test_table_codes_of_the_manuals_worked_examples():
    assert code_for_rate(3.38) == 0x56E5  # "runs fast by 3.38 s/day"
    assert code_for_rate(-5.62) == 0x5603  # "runs slow by 5.62 s/day"


@pytest.mark.slow
def test_drift_measured_compensated_and_remeasured(bench, s35390a, io, measure, report):
    io.write("D4054", 0x0000)
    duration = 86400.0 if bench.time.virtual else 6 * 3600.0
    before = s35390a.drift.measure(duration)
    report.attach_drift(before, "drift_uncompensated", title=f"uncompensated: {before.s_per_day:+.3f} s/day")
    measure("drift_uncompensated", before.s_per_day, unit="s/day")  # evidence only: the chip's own error
    code = s35390a.drift.compensate(before.s_per_day)
    assert io.read("D4054") == code == code_for_rate(before.s_per_day)
    after = s35390a.drift.measure(duration)
    report.attach_drift(after, "drift_residual", title=f"D4054 = {code:04X}H: residual {after.s_per_day:+.3f} s/day")
    # On a bench the polling resolution of a few hours' measurement adds to the manual's one fine step.
    limit = FINE_STEP + (0.0 if bench.time.virtual else after.resolution)
    measure("drift_residual", after.s_per_day, unit="s/day", low=-limit, high=limit,
            note=f"drift {before.s_per_day:+.3f} s/day, D4054 = {code:04X}H; a residual near twice the drift "
                 f"means the correction's sign is inverted")
    assert abs(after.s_per_day) <= limit, (
        f"drift {before.s_per_day:+.3f} s/day, D4054 = {code:04X}H, residual {after.s_per_day:+.3f} s/day "
        f"(limit ±{limit:.3f}); a residual near twice the drift means the correction's sign is inverted")
