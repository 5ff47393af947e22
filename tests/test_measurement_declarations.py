"""Measurements declared before a test runs (``@pytest.mark.measures``): UNSET until measured, and a test that
passes without measuring what it declared fails — no pass without evidence."""

from __future__ import annotations

from tests.conftest import EMULATOR_BENCH


def test_declared_measurements_are_unset_until_measured_and_a_pass_needs_them(pytester):
    pytester.makepyfile(test_declared="""
        import pytest

        @pytest.mark.measures("drift_residual", unit="s/day", low=-0.088, high=0.088)
        def test_measures_it(bench, measure):
            measure("drift_residual", 0.05)  # unit and limits come from the declaration

        @pytest.mark.measures("drift_residual", unit="s/day", low=-0.088, high=0.088)
        def test_out_of_its_declared_limits(bench, measure):
            measure("drift_residual", 0.5)

        @pytest.mark.measures("drift_residual", unit="s/day", low=-0.088, high=0.088)
        def test_forgets_to_measure(bench, measure):
            pass

        @pytest.mark.measures("drift_residual", unit="s/day", low=-0.088, high=0.088)
        def test_states_a_declared_limit_again(bench, measure):
            measure("drift_residual", 0.05, high=0.5)  # limits are declared once: refused, even in limits

        @pytest.mark.measures("settle_time", unit="s")
        def test_gives_what_the_declaration_left_out(bench, measure):
            assert measure("settle_time", 12.0, low=0, high=60).passed
    """)
    junit = pytester.path / "junit.xml"
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), f"--junitxml={junit}",
                                          "-p", "no:cacheprovider")
    result.assert_outcomes(passed=2, failed=3)
    result.stdout.fnmatch_lines(["*drift_residual = 0.5 s/day [[]-0.088, 0.088] FAIL*",
                                 "*declared measurement(s) never measured: drift_residual = (not measured)*UNSET*"])
    result.stdout.fnmatch_lines(["*measurement 'drift_residual': high declared by @pytest.mark.measures already*"])
    xml = junit.read_text()
    assert 'name="hil.measure.drift_residual.outcome" value="UNSET"' in xml
    assert 'name="hil.measure.drift_residual.unit" value="s/day"' in xml
    assert 'name="hil.measure.drift_residual.outcome" value="PASS"' in xml
