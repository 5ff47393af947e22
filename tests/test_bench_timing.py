"""Bench timing (hil.sim.timing): the emulator publishes what the manual lets a PLC do later, later — at phases
drawn from one seed, within the manual's envelope — and the seed replays it.  Virtual time throughout."""

from __future__ import annotations

import datetime as dt
import re
import tomllib
from pathlib import Path

import pytest

from hil.bench.profile import profile_from_dict
from hil.cli.emulate import with_timing
from hil.core.errors import ProfileError
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.models.temperature import TemperatureModel
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.temperature import EXEC_BAD_MODULE_COUNT, EXEC_MEASURING
from tests.conftest import EMULATOR_BENCH

EPOCH = dt.datetime(2026, 1, 1, 12, 0, 0)
TABLE, READINGS, WORK = 3000, 3020, 3060  # R addresses of fixtures/benches/emulator.toml's [temperature]
CYCLE = 6.0  # a 16TC's update time at the normal rate (manual 20.3)
POINTS = 16  # per 16TC


def bench_timed(seed: int, extra: str = "") -> dict:
    """The emulator's profile with ``[emulator] timing = "bench"`` and ``seed``."""
    text = EMULATOR_BENCH.read_text()
    text = re.sub(r"(?m)^seed = \d+$", f'seed = {seed}\ntiming = "bench"\n{extra}', text, count=1)
    return tomllib.loads(text)


def emulator(seed: int, extra: str = "") -> Emulator:
    return build_emulator(profile_from_dict(bench_timed(seed, extra), path=Path("bench.toml")), EPOCH)


def refreshes(emu: Emulator, until: float) -> list[tuple[float, int]]:
    """(time, point) of every change of a reading word, scan by scan up to ``until``."""
    seen: list[tuple[float, int]] = []
    before = list(emu.memory.words["R"][READINGS:READINGS + 2 * POINTS])
    while emu.now < until:
        emu.scan()
        now = emu.memory.words["R"][READINGS:READINGS + 2 * POINTS]
        seen += [(emu.now, p) for p in range(2 * POINTS) if now[p] != before[p]]
        before = list(now)
    return seen


def module_phases(emu: Emulator) -> list[float]:
    return list(emu.model(TemperatureModel)._next)  # each module's first refresh (before any scan)


def test_the_seed_replays_the_phases_and_another_seed_moves_them():
    assert module_phases(emulator(7)) == module_phases(emulator(7))
    assert module_phases(emulator(7)) != module_phases(emulator(8))
    phases = module_phases(emulator(7))
    assert all(0 < t <= CYCLE for t in phases) and phases[0] != phases[1], "each module at its own phase"


def test_instant_timing_stays_the_default():
    emu = build_emulator(profile_from_dict(tomllib.loads(EMULATOR_BENCH.read_text())), EPOCH)
    assert not emu.timing.bench and emu.model(TemperatureModel)._next == [CYCLE / POINTS] * 2


def test_each_module_refreshes_its_readings_once_per_period_at_its_phase():
    emu = emulator(3)
    first = module_phases(emu)
    seen = refreshes(emu, 4 * CYCLE)
    for k in range(2):
        points = set(range(k * POINTS, (k + 1) * POINTS))
        times = sorted({t for t, p in seen if p in points})
        # the noise moves some readings at every refresh, and no reading moves between two refreshes
        assert times, f"module {k} never refreshed"
        due = [first[k] + n * CYCLE for n in range(4)]
        for t in times:
            assert any(d - 1e-9 <= t < d + emu.scan_time * 2 for d in due), f"module {k} refreshed at {t:.3f} s"


def test_a_table_rewrite_takes_effect_at_the_next_cycle_not_at_once():
    emu = emulator(5)
    emu.advance(3 * CYCLE)
    words = emu.memory.words["R"]
    assert words[WORK] >> 8 == EXEC_MEASURING
    words[TABLE + 1] = 0  # no modules: FEH once the OS reads the table again
    written = emu.now
    codes = []
    while emu.now < written + CYCLE + 0.1:
        emu.scan()
        codes.append((emu.now, words[WORK] >> 8))
    changed = next(t for t, code in codes if code == EXEC_BAD_MODULE_COUNT)
    assert changed > written + emu.scan_time, "the rewrite took effect in the scan it was written"
    assert changed <= written + CYCLE + 0.05, "the rewrite waited longer than one cycle"
    assert all(code == EXEC_MEASURING for t, code in codes if t < changed)


def test_the_table_cycle_phase_replays_with_the_seed():
    def first_fe(seed: int) -> float:
        emu = emulator(seed)
        emu.advance(3 * CYCLE)
        emu.memory.words["R"][TABLE + 1] = 0
        while emu.memory.words["R"][WORK] >> 8 != EXEC_BAD_MODULE_COUNT:
            emu.scan()
        return round(emu.now, 6)
    assert first_fe(11) == first_fe(11)
    assert len({first_fe(s) for s in (11, 12, 13)}) > 1


def test_scan_lengths_stay_within_the_range_and_replay():
    def lengths(seed: int) -> list[float]:
        emu = emulator(seed, "scan_time_range = [5, 20]")
        out = []
        for _ in range(300):
            before = emu.now
            emu.scan()
            out.append(emu.now - before)
        return out
    drawn = lengths(4)
    assert all(0.005 - 1e-9 <= d <= 0.020 + 1e-9 for d in drawn)
    assert max(drawn) - min(drawn) > 0.01, "the scans do vary"
    assert drawn == lengths(4) and drawn != lengths(5)


def test_the_first_pid_step_comes_within_one_interval_of_en():
    emu = emulator(9)
    emu.advance(2 * CYCLE)  # every point measured: FUN86 may run
    fun86 = next(m for m in emu.models if m.name == "fun86")
    emu.memory.set("M0", 1)
    emu.scan()
    st = fun86.states[0]
    assert emu.now < st.next_pid <= emu.now + st.interval


def test_seed_and_timing_from_the_command_line_override_the_profile():
    profile = profile_from_dict(bench_timed(1))
    assert with_timing(profile, None, 42).emulator.timing_plan().seed == 42
    assert not with_timing(profile, "instant", None).emulator.timing_plan().bench


@pytest.mark.parametrize("line, says", [
    ('timing = "late"', r'bench\.toml: \[emulator\] timing = .late. must be one of instant, bench'),
    ("timing = 1", r"bench\.toml: \[emulator\] timing must be a str"),
    ("scan_time_range = [20, 5]", r"bench\.toml: \[emulator\] scan_time_range .* 0\.1 ≤ MIN ≤ MAX ≤ 1000"),
    ("scan_time_range = [5]", r"bench\.toml: \[emulator\] scan_time_range .* two numbers"),
    ('scan_time_range = "5-20"', r"bench\.toml: \[emulator\] scan_time_range must be a list"),
])
def test_bad_timing_keys_name_the_key_and_the_file(line, says):
    data = tomllib.loads(EMULATOR_BENCH.read_text().replace("seed = 0\n", f"seed = 0\n{line}\n", 1))
    with pytest.raises(ProfileError, match=says):
        profile_from_dict(data, path=Path("bench.toml"))


def test_a_scan_range_without_bench_timing_is_refused():
    data = tomllib.loads(EMULATOR_BENCH.read_text().replace("seed = 0\n", "seed = 0\nscan_time_range = [5, 20]\n", 1))
    with pytest.raises(ProfileError, match=r'bench\.toml: \[emulator\] scan_time_range .*timing = "bench"'):
        profile_from_dict(data, path=Path("bench.toml"))


@pytest.mark.parametrize("seed", range(2, 8))
def test_jumps_over_request_free_time_agree_with_scanning_every_scan(seed):
    """The engine's fast-forward (and FUN86's wake-ups) in bench timing leave what a scan-by-scan run leaves: the
    same readings, work block, FUN86 outputs and scan counter (seeds that put a module's refresh before and after
    the table cycle)."""
    def run(every_scan: bool) -> tuple[Emulator, list[int]]:
        emu = emulator(seed)

        def until(t: float) -> None:
            if not every_scan:
                emu.advance_to(t)
            while emu.now < t - 1e-9:
                emu.scan()
        until(13.0)
        # no table for a while (the next table cycle stops the measuring), sensors opened meanwhile: a jump over
        # the cycle must still take the measurements due before it under the valid table
        emu.memory.words["R"][TABLE] = 0xA557
        emu.scan()
        model = emu.model(TemperatureModel)
        for point in range(2 * POINTS):
            model.open(point)
        until(23.0)
        breaks = emu.memory.words["R"][WORK + 1:WORK + 3]
        emu.memory.words["R"][TABLE] = 0xA556
        for point in range(2 * POINTS):
            model.repair(point)
        until(40.0)
        emu.memory.set("M0", 1)  # zone-a's EN: PID steps, the plant heating
        until(80.0)
        return emu, breaks
    (jumped, jumped_breaks), (scanned, scanned_breaks) = run(False), run(True)
    assert jumped.scans < scanned.scans / 10, "the fast-forward jumped"
    assert jumped_breaks == scanned_breaks, "the break bits while the table was invalid"
    assert jumped.memory.words["R"] == scanned.memory.words["R"]
    assert jumped.memory.bits == scanned.memory.bits


def test_a_seed_replays_a_whole_run():
    """Everything bench timing draws — scan lengths, module and table phases, the plant's noise — comes from the
    seed: two runs of one seed leave the same memory at the same virtual time, another seed does not."""
    def run(seed: int) -> tuple[float, list[int]]:
        emu = emulator(seed, "scan_time_range = [5, 20]")
        emu.advance(13.0)
        emu.memory.set("M0", 1)
        emu.advance(30.0)
        return emu.now, list(emu.memory.words["R"])
    assert run(21) == run(21)
    assert run(21) != run(22)
