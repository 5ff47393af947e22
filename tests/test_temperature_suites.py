"""The temperature suites end to end: every emulator wire, an external ``hil emulate`` with a fault rig, and
broken emulators that the suites must catch (a suite that passes on a faulty PLC is the worst bug we can have)."""

from __future__ import annotations

import time

import numpy as np
import pytest

# Imported here, outside the inner runs: pytester restores sys.modules after each inner run, so whatever the
# inner run imports first is imported (and assertion-rewritten, being part of the plugin's distribution) again
# in every run — seconds per run.
import hil.families.fbs.device.temperature  # noqa: F401
import hil.families.fbs.sim.serve_fatek  # noqa: F401
import hil.families.fbs.sim.serve_modbus  # noqa: F401
import hil.families.fbs.faults  # noqa: F401
import hil.plugin.pytest_plugin  # noqa: F401
import hil.families.fbs.transport.fatek  # noqa: F401
import hil.families.fbs.transport.local  # noqa: F401
import hil.families.fbs.transport.modbus  # noqa: F401
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.models.temperature import TemperatureModel
from tests.conftest import EMULATOR_BENCH, EMULATOR_TARGETS, REPO
from tests.external import bench_over_the_wire, hil_emulate

SUITE = str(REPO / "suites" / "test_temperature.py")
SUITE_TESTS = 6  # 2 + 1 × 4 points
# The inner runs need no hypothesis; loading its plugin re-imports (and rewrites) ~70 modules per run.
INNER = ("-p", "no:hypothesispytest")


@pytest.mark.parametrize("target", EMULATOR_TARGETS)
def test_temperature_suite_passes_on_every_emulator_target(pytester, target):
    result = pytester.runpytest_inprocess(SUITE, *INNER, "--bench", str(EMULATOR_BENCH), "--target", target)
    result.assert_outcomes(passed=SUITE_TESTS)


# -- broken emulators -------------------------------------------------------------------------------------------
class BreakValue28766(TemperatureModel):
    def point_result(self, point, installed, broken, live):
        reading, flag = super().point_result(point, installed, broken, live)
        return np.where(broken & installed, 28766, reading), flag


class BreakValueZero(TemperatureModel):
    def point_result(self, point, installed, broken, live):
        reading, flag = super().point_result(point, installed, broken, live)
        return np.where(broken & installed, 0, reading), flag


class BreakBitOnNextPoint(TemperatureModel):
    def break_position(self, point):
        return super().break_position((point + 1) % 32)


class UnfittedPointStillFlagged(TemperatureModel):
    def point_result(self, point, installed, broken, live):
        reading, flag = super().point_result(point, installed, broken, live)
        return reading, flag | broken


class R4011Ignored(TemperatureModel):
    """Takes every point's installed bit from R4010 (point % 16): R4011 is never read."""

    def installed(self, mem, point):
        return super().installed(mem, point % 16)


class BreakBitsOfHighPointsInTW1(TemperatureModel):
    def break_position(self, point):
        return 1, point % 16


class MaskLatchedAtPowerOn(TemperatureModel):
    def power_on(self, emu):
        super().power_on(emu)
        self._latched = list(emu.memory.words["R"][4010:4012])

    def installed(self, mem, point):
        return (np.array(self._latched)[point // 16] >> (point % 16) & 1).astype(bool)


class ExecutionCode55(TemperatureModel):
    def execution_code(self, state, all_measured):
        code = super().execution_code(state, all_measured)
        return 0x55 if code == 0x56 else code


class RepairNeverSeen(TemperatureModel):
    def repair(self, point):
        pass


class Variant:
    """A plugin for the inner pytest run whose emulator has ``model_class`` in place of the temperature model."""

    def __init__(self, model_class: type[TemperatureModel]) -> None:
        self.model_class = model_class

    def pytest_hil_make_emulator(self, profile, epoch):  # noqa: ANN001, ANN201
        emulator = build_emulator(profile, epoch)
        good = emulator.model(TemperatureModel)
        emulator.models.remove(good)
        emulator.add_model(self.model_class(good.config))
        return emulator


# variant → the suite tests that must catch it (each listed test must fail)
CAUGHT_BY = {
    BreakValue28766: ["test_a_sensor_broken_masked_unmasked_and_repaired"],
    BreakValueZero: ["test_a_sensor_broken_masked_unmasked_and_repaired"],
    BreakBitOnNextPoint: ["test_a_sensor_broken_masked_unmasked_and_repaired"],
    UnfittedPointStillFlagged: ["test_a_sensor_broken_masked_unmasked_and_repaired"],
    R4011Ignored: ["test_a_sensor_broken_masked_unmasked_and_repaired[first-high]",
                   "test_a_sensor_broken_masked_unmasked_and_repaired[last-high]"],
    BreakBitsOfHighPointsInTW1: ["test_a_sensor_broken_masked_unmasked_and_repaired[first-high]",
                                 "test_a_sensor_broken_masked_unmasked_and_repaired[last-high]"],
    MaskLatchedAtPowerOn: ["test_a_sensor_broken_masked_unmasked_and_repaired"],
    ExecutionCode55: ["test_table_is_recognised_and_measuring"],
    RepairNeverSeen: ["test_a_sensor_broken_masked_unmasked_and_repaired"],
}


@pytest.mark.parametrize("variant", list(CAUGHT_BY), ids=lambda v: v.__name__)
def test_the_suite_catches_a_broken_emulator(pytester, variant):
    result = pytester.inline_run(SUITE, *INNER, "--bench", str(EMULATOR_BENCH), plugins=[Variant(variant)])
    failed = {r.nodeid.split("::")[-1] for r in result.getreports("pytest_runtest_logreport")
              if r.when == "call" and r.failed}
    for name in CAUGHT_BY[variant]:
        assert any(f == name or f.startswith(name + "[") for f in failed), (
            f"{variant.__name__} passed {name}; failed only: {sorted(failed)}")


def test_the_correct_emulator_passes_through_the_same_hook(pytester):
    result = pytester.inline_run(SUITE, *INNER, "--bench", str(EMULATOR_BENCH), plugins=[Variant(TemperatureModel)])
    result.assertoutcome(passed=SUITE_TESTS)


# -- an external emulator, reached only over the wire, sensors opened through the fault rig ---------------------
TIME_SCALE = 100


def test_temperature_suite_against_hil_emulate_with_a_modbus_coil_rig(pytester, tmp_path):
    (tmp_path / "emulated.toml").write_text(EMULATOR_BENCH.read_text())
    with hil_emulate(tmp_path / "emulated.toml", TIME_SCALE) as where:
        bench_file = tmp_path / "client.toml"
        bench_file.write_text(bench_over_the_wire(EMULATOR_BENCH.read_text(), where, TIME_SCALE))
        started = time.monotonic()
        result = pytester.runpytest_inprocess(SUITE, *INNER, "--bench", str(bench_file), "-rs")
        elapsed = time.monotonic() - started
        result.assert_outcomes(passed=SUITE_TESTS)
        assert elapsed < 30, f"the external-emulator run took {elapsed:.1f} s"
