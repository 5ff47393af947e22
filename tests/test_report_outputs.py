"""Outputs as registered callbacks, each handed the run's record (hil.plugin.reporting.outputs): a third output is
one registration, sees every moment of the run and each test's outcome — never more than its reports showed."""

from __future__ import annotations

import pytest

from hil.plugin.reporting.model import TestOutcome, TestRecord
from hil.plugin.reporting.outputs import OUTPUTS, RUN, Moment, RunRecord
from tests.conftest import EMULATOR_BENCH


def test_a_registered_output_gets_the_record_at_every_moment(pytester, monkeypatch):
    seen: list[tuple[Moment, dict[str, str], str]] = []

    def output(moment: Moment, run: RunRecord) -> None:
        assert run.config.stash[RUN] is run  # the one typed stash key
        seen.append((moment, {k.rpartition("::")[2]: v.outcome for k, v in run.records.items()},
                     run.verdict.status if run.verdict else ""))
    monkeypatch.setitem(OUTPUTS._items, "test-output", output)  # registered for this test only
    pytester.makepyfile(test_outputs="""
        import pytest

        @pytest.fixture
        def broken(bench):
            raise RuntimeError("setup fails")

        def test_passes(bench):
            pass

        def test_fails(bench):
            assert False

        def test_skips(bench):
            pytest.skip("nothing to check here")

        @pytest.mark.xfail(reason="known")
        def test_xfails(bench):
            assert False

        def test_errors(broken):
            pass
    """)
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, failed=1, skipped=1, xfailed=1, errors=1)
    assert [moment for moment, _, _ in seen] == [Moment.STARTED, Moment.SUMMARY, Moment.FINISHED, Moment.CLOSED]
    assert seen[0][1] == {} and seen[0][2] == "INCOMPLETE"  # nothing has run: nothing is said of a test
    assert seen[2][1] == {"test_passes": "passed", "test_fails": "failed", "test_skips": "skipped",
                          "test_xfails": "xfailed", "test_errors": "error"} and seen[2][2] == "FAILED"


def test_a_record_has_no_result_until_a_report_gives_it_one():
    record = TestRecord("t::a", "x")
    assert record.outcome is TestOutcome.INCOMPLETE and record.outcome.bad
    assert TestRecord("t::b", "x", outcome="aborted").outcome is TestOutcome.ABORTED  # read back as a word
    assert not TestOutcome.PASS.bad and not TestOutcome.SKIP.bad and TestOutcome.ABORTED.bad
    with pytest.raises(ValueError):
        TestRecord("t::c", "x", outcome="passed-ish")
