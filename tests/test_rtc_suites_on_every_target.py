"""The RTC suites pass on every emulator target; over Modbus, D4053/D4054 checks skip naming the map."""

from __future__ import annotations

import pytest

from tests.conftest import EMULATOR_BENCH, REPO, over_targets

RTC_SUITES = [str(REPO / "suites" / f) for f in
              ("test_rtc.py", "test_rtc_midnight.py", "test_rtc_validity.py", "test_rtc_adjust.py",
               "test_rtc_drift.py")]


@pytest.mark.parametrize("target", over_targets("emulator+modbus-rtu"))
def test_rtc_suites_pass(pytester, target):
    result = pytester.runpytest_inprocess(*RTC_SUITES, "--bench", str(EMULATOR_BENCH), "--target", target, "-rs",
                                          "-p", "no:cacheprovider", "-p", "no:hypothesispytest")
    outcomes = result.parseoutcomes()
    assert outcomes.get("failed", 0) == 0 and outcomes.get("error", 0) == 0, result.stdout.str()[-3000:]
    assert outcomes["passed"] >= 20  # cases that share a wait are folded into one test each
    # the no-chip check runs only where the profile says the PLC has no RTC chip
    result.stdout.fnmatch_lines(["*the bench profile does not say this PLC has no RTC chip*"])
    if "modbus" in target:
        # D4054 is unreachable over the default Modbus map: those tests skip and say why.
        assert outcomes.get("skipped", 0) >= 2
        result.stdout.fnmatch_lines(["*D4054 cannot be reached over the default FBs Modbus map*"])
    else:
        assert outcomes.get("skipped", 0) == 1
