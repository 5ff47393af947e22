"""No pass without evidence: the drift test fails as inconclusive when its measurement cannot get below the
manual's fine step (0.088 s/day) within the bench's [rtc] drift_max_hours, and never widens its limit instead."""

from __future__ import annotations

from hil.families.fbs.sim.models.rtc import RtcModel
from tests.broken import BrokenEmulator, replace_model
from tests.conftest import EMULATOR_BENCH, REPO

DRIFT = str(REPO / "suites" / "test_rtc_drift.py")
INNER = ("-p", "no:cacheprovider", "-p", "no:hypothesispytest", "-k", "drift_measured", "-rsf")


def _profile(tmp_path, max_hours: float):
    path = tmp_path / "bench.toml"
    path.write_text(EMULATOR_BENCH.read_text().replace("[rtc]\n", f"[rtc]\ndrift_max_hours = {max_hours}\n", 1))
    return path


def test_drift_test_fails_as_inconclusive_when_the_resolution_cannot_reach_the_fine_step(pytester, tmp_path):
    # 20 ms polls over at most 30 min: ≈ 1 s/day of resolution, far above 0.088 s/day
    result = pytester.runpytest_inprocess(DRIFT, "--bench", str(_profile(tmp_path, 0.5)), *INNER)
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*inconclusive*resolution*not below the manual's fine step 0.088*"])


def test_drift_test_skips_naming_the_key_on_a_bench_that_does_not_measure_drift(pytester, tmp_path):
    result = pytester.runpytest_inprocess(DRIFT, "--bench", str(_profile(tmp_path, 0)), *INNER)
    result.assert_outcomes(skipped=1)
    result.stdout.fnmatch_lines(["*drift_max_hours = 0*"])


class D4054Ignored(RtcModel):
    """Takes the D4054 write but never corrects the rate."""

    def correction_rate(self, code):
        return 0.0


def test_drift_test_fails_on_a_plc_that_ignores_d4054(pytester):
    def breakage(emulator, profile, epoch):
        rtc = profile.rtc
        replace_model(emulator, RtcModel, D4054Ignored(chip=rtc.chip, crystal_ppm=rtc.crystal_ppm,
                                                       start=rtc.start or epoch))
    result = pytester.runpytest_inprocess(DRIFT, "--bench", str(EMULATOR_BENCH), *INNER,
                                          plugins=[BrokenEmulator(breakage)])
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*drift_residual = 3.*[[]-0.088, 0.088[]] FAIL*"])
