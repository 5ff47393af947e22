"""The temperature suites end to end: every emulator wire, an external ``hil emulate`` with a fault rig, and
broken emulators that the suites must catch (a suite that passes on a faulty PLC is the worst bug we can have)."""

from __future__ import annotations

import re

import numpy as np
import pytest

# Imported here, outside the inner runs: pytester restores sys.modules after each inner run, so whatever the
# inner run imports first is imported (and assertion-rewritten, being part of the plugin's distribution) again
# in every run — seconds per run.
import hil.families.fbs.device.temperature
import hil.families.fbs.faults
import hil.families.fbs.sim.serve_fatek
import hil.families.fbs.sim.serve_modbus
import hil.families.fbs.transport.fatek
import hil.families.fbs.transport.local
import hil.families.fbs.transport.modbus
import hil.plugin.pytest_plugin  # noqa: F401
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.models.temperature import TemperatureModel
from hil.families.fbs.temperature import EXEC_BAD_MODULE_COUNT, EXEC_IDLE, EXEC_MEASURING, TABLE_MARKER
from tests.conftest import EMULATOR_BENCH, EMULATOR_TARGETS, REPO
from tests.external import bench_over_the_wire, hil_emulate

SUITE = str(REPO / "suites" / "test_temperature.py")
SUITE_TESTS = 8
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


class MaskHidesOnlyOpenSensors(TemperatureModel):
    """A masked point reads 0 only while its sensor is open; a healthy masked one shows its live reading."""

    def installed(self, mem, point):
        return super().installed(mem, point) | ~np.isin(point, list(self.broken))


class Point16MaskedByR4010(TemperatureModel):
    """Point 16's installed bit read from R4010 bit 0 (point // 17 for the word): it follows point 0's."""

    def installed(self, mem, point):
        mask = np.array(mem.words["R"][4010:4012])
        return (mask[point // 17] >> (point % 16) & 1).astype(bool)


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


class CelsiusWhenFahrenheit(TemperatureModel):
    """Reports °C whatever unit the table asks for (caught on a °F profile)."""

    def in_unit(self, celsius, low, high):
        if low is not None:
            celsius = np.minimum(np.maximum(celsius, low), high)
        return celsius


class WholeDegreesAtNormalRate(TemperatureModel):
    """Whole degrees at the normal rate too (the manual: 0.1 ° there)."""

    def resolution(self, mean):
        return np.rint(mean) * 10.0


class NoFEHForCountZero(TemperatureModel):
    """A table with module count 0 reads as idle (00H), not FEH."""

    def scan(self, emu):
        self._table_count = emu.memory.words[self.config.table.kind][self.config.table.index + 1]
        super().scan(emu)

    def execution_code(self, state, all_measured):
        code = super().execution_code(state, all_measured)
        return EXEC_IDLE if code == EXEC_BAD_MODULE_COUNT and self._table_count == 0 else code


class CountByteModulo255(TemperatureModel):
    """TW+3's module count byte is the count modulo 255 rather than its low byte: a count of FFH reads 0."""

    def _write_work(self, mem, work, block, table):
        count = block[3] & 0xFF
        super()._write_work(mem, work, [*block[:3], block[3] - count + count % 0xFF, *block[4:]], table)


class NoFFHForTooManyPoints(TemperatureModel):
    """More than 32 points still reports 56H."""

    def execution_code(self, state, all_measured):
        return EXEC_MEASURING if state == "too_many_points" else super().execution_code(state, all_measured)


class MismatchBitsNeverSet(TemperatureModel):
    def _plan(self, codes, table_modules, readings_word):
        mismatch, *rest = super()._plan(codes, table_modules, readings_word)
        return (0, *rest)


class AnyModuleNameMatches(TemperatureModel):
    """A table entry naming any module kind is taken as the module fitted: only an unknown name (FFH) is flagged
    in TW+0's low byte (mutant temperature.py:246)."""

    def _plan(self, codes, table_modules, readings_word):
        named = [self.fitted[k] if tm is not None and k < len(self.fitted) else tm
                 for k, tm in enumerate(table_modules)]
        return super()._plan(codes, named, readings_word)


class _MarkerAlsoAccepted(TemperatureModel):
    """Takes the table as valid with SR+0 = ``also`` too (not only A556H)."""

    also = 0

    def scan(self, emu):
        words, sr = emu.memory.words[self.config.table.kind], self.config.table.index
        marker = words[sr]
        if marker == self.also:
            words[sr] = TABLE_MARKER
        try:
            super().scan(emu)
        finally:
            words[sr] = marker


class MarkerAboveA556HAccepted(_MarkerAlsoAccepted):
    """A table with SR+0 = A557H is measured (the marker compared with ≥, mutant temperature.py:275)."""

    also = 0xA557


class ByteSwappedMarkerAccepted(_MarkerAlsoAccepted):
    """A table with SR+0 = 56A5H (A556H byte-swapped) is measured."""

    also = 0x56A5


class EveryEntryStartsAtSR2(TemperatureModel):
    """The per-module entries all give the table's readings start (TW+6+4k = SR+2)."""

    def _plan(self, codes, table_modules, readings_word):
        mismatch, expected, entries, measured = super()._plan(codes, table_modules, readings_word)
        entries = list(entries)
        for k in range(len(entries) // 4):
            entries[4 * k + 2] = readings_word & 0xFFFF
        return mismatch, expected, tuple(entries), measured


class BreakWordsHoldOnePoint(TemperatureModel):
    """TW+1/TW+2 show only the highest broken point (one point's flag, not a bit per point)."""

    def _compute_break_words(self):
        low, high = super()._compute_break_words()
        bits = high << 16 | low
        top = 1 << (bits.bit_length() - 1) if bits else 0
        return top & 0xFFFF, top >> 16


class R4011DefaultsTo0000(TemperatureModel):
    """R4011 powers on as 0000H (points 16–31 not fitted), not FFFFH."""

    def power_on(self, emu):
        super().power_on(emu)
        emu.memory.words["R"][4011] = 0


class UpdateTimeOneAndAHalf(TemperatureModel):
    """Each point measured every 1.5 × the manual's update time."""

    def _step(self, module):
        return 1.5 * super()._step(module)


class Variant:
    """A plugin for the inner pytest run whose emulator has ``model_class`` in place of the temperature model."""

    def __init__(self, model_class: type[TemperatureModel]) -> None:
        self.model_class = model_class

    def pytest_hil_make_emulator(self, profile, epoch):
        emulator = build_emulator(profile, epoch)
        good = emulator.model(TemperatureModel)
        emulator.models.remove(good)
        emulator.add_model(self.model_class(good.config))
        return emulator


# variant → the suite tests that must catch it (each listed test must fail)
BREAK_TEST = "test_sensors_broken_masked_unmasked_and_repaired"
CAUGHT_BY = {
    BreakValue28766: [BREAK_TEST],
    BreakValueZero: [BREAK_TEST],
    BreakBitOnNextPoint: [BREAK_TEST],
    UnfittedPointStillFlagged: [BREAK_TEST],
    R4011Ignored: [BREAK_TEST],
    BreakBitsOfHighPointsInTW1: [BREAK_TEST],
    MaskLatchedAtPowerOn: [BREAK_TEST],
    ExecutionCode55: ["test_table_is_recognised_and_measuring"],
    RepairNeverSeen: [BREAK_TEST],
    CelsiusWhenFahrenheit: ["test_readings_are_in_range_and_units"],
    WholeDegreesAtNormalRate: ["test_readings_are_in_range_and_units"],
    NoFEHForCountZero: ["test_work_block_codes_for_a_table_that_does_not_fit"],
    CountByteModulo255: ["test_work_block_codes_for_a_table_that_does_not_fit"],
    NoFFHForTooManyPoints: ["test_work_block_codes_for_a_table_that_does_not_fit"],
    MismatchBitsNeverSet: ["test_work_block_codes_for_a_table_that_does_not_fit"],
    AnyModuleNameMatches: ["test_work_block_codes_for_a_table_that_does_not_fit"],
    MarkerAboveA556HAccepted: ["test_nothing_is_measured_while_sr0_is_not_a556h"],
    ByteSwappedMarkerAccepted: ["test_nothing_is_measured_while_sr0_is_not_a556h"],
    EveryEntryStartsAtSR2: ["test_table_is_recognised_and_measuring"],
    BreakWordsHoldOnePoint: [BREAK_TEST],
    R4011DefaultsTo0000: ["test_installed_mask_defaults_to_ffffh"],
    UpdateTimeOneAndAHalf: [BREAK_TEST],
    MaskHidesOnlyOpenSensors: [BREAK_TEST],
    Point16MaskedByR4010: [BREAK_TEST],
}


def mixed_profile(text: str) -> str:
    """The emulator's profile with 8 modules of every kind but the 16-point ones, other sensors (B, E, N, R,
    NTC 2K and 20K, PT100, T), in °F at the fast rate with 4-sample averaging, the table at an odd register (SR
    R3001: a PLC may keep it anywhere — one that found SR + 1 as SR ^ 1 reads an even SR's count right): the other
    half of the domain."""
    modules = ('modules = [{type = "2TC", sensor = "B"}, {type = "2TC", sensor = "E"}, {type = "2TC", sensor = "N"}, '
               '{type = "2TC", sensor = "R"}, {type = "6NTC", sensor = "2K"}, {type = "6RTD", sensor = "PT100"}, '
               '{type = "6TC", sensor = "T"}, {type = "6NTC", sensor = "20K"}]')
    out = re.sub(r"(?m)^modules = \[.*\]$", modules, text, count=1)
    out = out.replace('unit = "C"', 'unit = "F"', 1).replace('rate = "normal"', 'rate = "fast"', 1)
    out = out.replace("averaging = 1", "averaging = 4", 1)
    out = out.replace('table = "R3000"', 'table = "R3001"', 1).replace('"R3000-R3011"', '"R3001-R3012"', 1)
    assert out.count('type = "2TC"') == 4 and 'unit = "F"' in out and 'rate = "fast"' in out
    assert 'table = "R3001"' in out and '"R3001-R3012"' in out
    return out


#: variants a profile other than the default one shows (the test of hil emulate uses the same)
PROFILE_FOR = {"CelsiusWhenFahrenheit": mixed_profile}


def _profile(tmp_path, variant) -> str:
    transform = PROFILE_FOR.get(variant.__name__)
    if transform is None:
        return str(EMULATOR_BENCH)
    path = tmp_path / f"{variant.__name__}.toml"
    path.write_text(transform(EMULATOR_BENCH.read_text()))
    return str(path)


@pytest.mark.parametrize("variant", list(CAUGHT_BY), ids=lambda v: v.__name__)
def test_the_suite_catches_a_broken_emulator(pytester, tmp_path, variant):
    only = ("-k", " or ".join(CAUGHT_BY[variant]))  # only the tests that must catch it run (CI time)
    result = pytester.inline_run(SUITE, *INNER, *only, "--bench", _profile(tmp_path, variant),
                                 plugins=[Variant(variant)])
    failed = {r.nodeid.split("::")[-1] for r in result.getreports("pytest_runtest_logreport")
              if r.when == "call" and r.failed}
    for name in CAUGHT_BY[variant]:
        assert any(f == name or f.startswith(name + "[") for f in failed), (
            f"{variant.__name__} passed {name}; failed only: {sorted(failed)}")


def test_the_correct_emulator_passes_through_the_same_hook(pytester):
    result = pytester.inline_run(SUITE, *INNER, "--bench", str(EMULATOR_BENCH), plugins=[Variant(TemperatureModel)])
    result.assertoutcome(passed=SUITE_TESTS)


@pytest.mark.parametrize("target", ["emulator", "emulator+modbus-rtu"])
def test_the_suite_passes_on_the_mixed_fahrenheit_fast_profile(pytester, tmp_path, target):
    """The other modules, sensors, unit and rate (mixed_profile), in process and over a serial Modbus line."""
    bench = tmp_path / "mixed.toml"
    bench.write_text(mixed_profile(EMULATOR_BENCH.read_text()))
    result = pytester.runpytest_inprocess(SUITE, *INNER, "--bench", str(bench), "--target", target)
    result.assert_outcomes(passed=SUITE_TESTS)


# -- an external emulator, reached only over the wire, sensors opened through the fault rig ---------------------
TIME_SCALE = 100


@pytest.mark.e2e
def test_temperature_suite_against_hil_emulate_with_a_modbus_coil_rig(pytester, tmp_path):
    (tmp_path / "emulated.toml").write_text(EMULATOR_BENCH.read_text())
    with hil_emulate(tmp_path / "emulated.toml", TIME_SCALE) as where:
        bench_file = tmp_path / "client.toml"
        bench_file.write_text(bench_over_the_wire(EMULATOR_BENCH.read_text(), where, TIME_SCALE))
        # (bench_over_the_wire makes the reply timeout a hang guard; the run's wall time against the same suite
        # in process is a benchmark's figure: benchmarks/bench_host_time.py)
        result = pytester.runpytest_inprocess(SUITE, *INNER, "--bench", str(bench_file), "-rs")
        # (the R4010/R4011 power-on defaults need power_on_state, which this profile does not offer: skipped)
        result.assert_outcomes(passed=SUITE_TESTS - 1, skipped=1)
