"""A suite's wait must be satisfied by what its stimulus produced: ``bench.expect`` looks before the stimulus, and a
condition that already holds then is a test error naming the wait (hil.core.evidence)."""

from __future__ import annotations

import datetime as dt

import pytest

from hil.core.evidence import StaleEvidence, expect
from tests.conftest import EMULATOR_BENCH


class VirtualTime:
    """Bench time that only a wait moves (the Timebase protocol)."""

    virtual = True

    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t

    def calendar(self) -> dt.datetime:
        return dt.datetime(2024, 1, 1) + dt.timedelta(seconds=self.t)

    def wait(self, seconds: float) -> None:
        self.t += seconds


def test_a_condition_true_before_the_stimulus_is_refused_naming_the_wait():
    clock = VirtualTime()
    with pytest.raises(StaleEvidence, match="'TW\\+3 counts 9 modules' was already satisfied before its stimulus"):
        expect(clock, "TW+3 counts 9 modules", lambda: True)
    assert clock.now() == 0.0  # looked once, waited for nothing


def test_a_fresh_wait_polls_at_its_cadence_until_the_condition_holds_or_the_limit():
    clock = VirtualTime()
    looks: list[float] = []

    def arrives_at_3s() -> bool:
        looks.append(clock.now())
        return clock.now() >= 3.0

    awaited = expect(clock, "the value changes", arrives_at_3s)
    assert awaited.within(10.0, every=0.5)
    assert looks[-1] == 3.0 and looks[1:] == [0.5 * k for k in range(7)]  # (looks[0]: the look before)
    never = expect(clock, "a change that never comes", lambda: False)
    started = clock.now()
    assert not never.within(4.0, every=1.5)
    assert clock.now() - started == pytest.approx(4.0)  # the whole limit, no more


def test_the_plugin_reports_a_stale_wait_as_an_error_of_the_test(pytester):
    pytester.makepyfile(test_waits="""
        def test_stale_wait(bench):
            io = bench.plc.io
            io.write("R1000", 7)
            bench.settle()
            awaited = bench.expect("R1000 holds 7", lambda: io.read("R1000") == 7)
            io.write("R1000", 7)  # the stimulus: the PLC showed its answer before it
            assert awaited.within(1.0)

        def test_fresh_wait(bench):
            io = bench.plc.io
            awaited = bench.expect("R1001 holds 8", lambda: io.read("R1001") == 8)
            io.write("R1001", 8)
            assert awaited.within(1.0)

        def test_wait_for_what_never_comes(bench):
            io = bench.plc.io
            awaited = bench.expect("R1002 holds 9", lambda: io.read("R1002") == 9)
            assert awaited.within(1.0), "R1002 never held 9"
    """)
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), "-rfE", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, failed=1, errors=1)
    result.stdout.fnmatch_lines([("*StaleEvidence: the wait for 'R1000 holds 7' was already satisfied before its "
                                  "stimulus*"), "ERROR (stale evidence) *test_stale_wait*"])
    result.stdout.fnmatch_lines(["E*AssertionError: R1002 never held 9", "FAILED *test_wait_for_what_never_comes*"])
    assert result.ret == 1
