"""The temperature suite over the whole domain of its rules: readings below 0 °C, each module's own update time, and
a table rewrite taken at the PLC's next cycle.  Each broken variant is a tiny subclass of the temperature model that
breaks exactly one rule, and the suite test stating that rule must FAIL on it; the correct emulator — and the same
in bench timing, slow where the manual lets it be — must PASS."""

from __future__ import annotations

import numpy as np
import pytest

from hil.families.fbs.sim.models.temperature import TemperatureModel
from tests.broken import BrokenEmulator, replace_model, run_suites
from tests.conftest import EMULATOR_BENCH
from tests.test_temperature_suites import SUITE_TESTS, mixed_profile

SUITE = "test_temperature.py"
BELOW_ZERO = "test_a_reading_below_zero_is_a_signed_word"
OWN_UPDATE = "test_each_module_shows_a_change_within_its_own_update_time"
TABLE_CODES = "test_work_block_codes_for_a_table_that_does_not_fit"


class ReadingsClampedAtZero(TemperatureModel):
    """A reading below zero shows 0 (an unsigned conversion that saturates)."""

    def resolution(self, mean):
        return np.maximum(super().resolution(mean), 0.0)


class SignDropped(TemperatureModel):
    """A reading below zero shows its magnitude: −20.5 ° reads 205."""

    def resolution(self, mean):
        return np.abs(super().resolution(mean))


class EveryModuleOnTheSlowestCycle(TemperatureModel):
    """Every module goes round its points once per the slowest fitted module's update time (a 1 s 6NTC beside a
    2 s 6TC refreshes every 2 s)."""

    def _step(self, module):
        slowest = max(m.update_s[self.config.rate] for m in self.fitted)
        return slowest / module.points


def _with(model_class: type[TemperatureModel]) -> BrokenEmulator:
    """The profile's emulator with ``model_class`` in place of its temperature model."""

    def swap(emulator, profile, epoch):
        replace_model(emulator, TemperatureModel, model_class(emulator.model(TemperatureModel).config))

    return BrokenEmulator(swap)


def _bench(tmp_path, profile: str):
    """The emulator bench (``default``: 2 × 16TC K/J, °C, normal rate) or the mixed one (2TC, 6NTC, 6RTD and 6TC
    side by side, °F, fast rate: modules with different update times)."""
    if profile == "default":
        return EMULATOR_BENCH
    path = tmp_path / "mixed.toml"
    path.write_text(mixed_profile(EMULATOR_BENCH.read_text()))
    return path


# variant → (the suite test that must fail on it, the profiles it shows on)
CAUGHT_BY = {
    ReadingsClampedAtZero: (BELOW_ZERO, ["default", "mixed"]),
    SignDropped: (BELOW_ZERO, ["default", "mixed"]),
    # (2 × 16TC have one update time: only modules of different ones show it)
    EveryModuleOnTheSlowestCycle: (OWN_UPDATE, ["mixed"]),
}


@pytest.mark.parametrize(("variant", "profile"), [(v, p) for v, (_, ps) in CAUGHT_BY.items() for p in ps],
                         ids=lambda x: x if isinstance(x, str) else x.__name__)
def test_the_suite_fails_on_a_broken_plc(pytester, tmp_path, variant, profile):
    name = CAUGHT_BY[variant][0]
    passed, failed = run_suites(pytester, [SUITE], _with(variant), "-k", name, bench=_bench(tmp_path, profile))
    assert [f.split("::")[-1] for f in failed] == [name], f"{variant.__name__}: passed {passed}, failed {failed}"


@pytest.mark.parametrize("profile", ["default", "mixed"])
def test_the_new_checks_pass_on_the_correct_emulator(pytester, tmp_path, profile):
    names = [BELOW_ZERO, OWN_UPDATE]
    passed, failed = run_suites(pytester, [SUITE], _with(TemperatureModel), "-k", " or ".join(names),
                                bench=_bench(tmp_path, profile))
    assert not failed and sorted(p.split("::")[-1] for p in passed) == sorted(names), (passed, failed)


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("profile", ["default", "mixed"])
def test_the_suite_passes_on_a_plc_that_times_things_as_a_bench_may(pytester, tmp_path, profile, seed):
    """Slow where the manual lets it be, and right — the emulator in bench timing (hil.sim.timing: each module
    refreshes once per update time at its own phase, a table rewrite acts at the next cycle): the whole suite
    passes.  (The module-count check once read TW+3 before such a PLC had taken the new count, and the marker check
    opened sensors before it had taken A557H.)"""
    text = _bench(tmp_path, profile).read_text()
    assert "\nseed = 0\n" in text, "the emulator profile sets [emulator] seed"
    timed = tmp_path / "bench-timed.toml"
    timed.write_text(text.replace("\nseed = 0\n", f'\nseed = {seed}\ntiming = "bench"\n', 1))
    passed, failed = run_suites(pytester, [SUITE], None, bench=timed)
    assert not failed and len(passed) == SUITE_TESTS, (passed, failed)
