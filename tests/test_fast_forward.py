"""Fast-forward must not change results: jumping virtual time equals stepping it scan by scan."""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable

import pytest

from hil.bench.profile import load_profile, profile_from_dict
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.models.temperature import resume_after_jump
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.temperature import AVERAGING, MODULES
from tests.conftest import EMULATOR_BENCH

EPOCH = dt.datetime(2024, 2, 28, 23, 0, 0)


def ramped_profile(averaging: int):
    base = load_profile(EMULATOR_BENCH)
    temperature = dict(base.areas["temperature"], averaging=averaging, sources={
        "0": {"kind": "ramp", "start": 20.0, "per_s": 0.37},
        "17": {"kind": "ramp", "start": 300.0, "per_s": -0.11, "low": 100.0},
        "31": {"kind": "fixed", "celsius": 55.5},
    })
    return profile_from_dict({"bench": {"name": "ff"}, "rtc": {"chip": 3, "crystal_ppm": 12.5},
                              "temperature": temperature})


@pytest.mark.parametrize("averaging", [1, 4])
@pytest.mark.parametrize("seconds", [7.3, 95.0, 600.0])
def test_jump_equals_stepping(averaging, seconds):
    profile = ramped_profile(averaging)
    stepped, jumped = build_emulator(profile, EPOCH), build_emulator(profile, EPOCH)
    for _ in range(round(seconds / stepped.scan_time)):
        stepped.scan()
    jumped.advance_to(stepped.now)  # the same instant, whatever float rounding did to the stepped clock
    assert jumped.now == stepped.now
    for first, count in (("R3020", 32), ("R3060", 12), ("R4128", 8)):
        assert jumped.memory.read(first, count) == stepped.memory.read(first, count), first


@pytest.mark.parametrize("averaging", AVERAGING)
@pytest.mark.parametrize("cycle", sorted({s for m in MODULES.values() for s in m.update_s.values()}))
def test_a_long_jump_measures_again_only_what_a_reading_shows(averaging, cycle):
    """After a virtual day a module's measurements resume a few cycles before now: at least the last ``averaging``
    whole cycles (every sample a reading averages: the jump equals stepping, above) and less than ``averaging`` + 2
    (the work of a catch-up is bounded — not the day's 14,400 rounds of a 6 s module in one scan)."""
    now = 86400.37
    resumed = resume_after_jump(0.0, now, cycle, averaging)
    assert averaging * cycle <= now - resumed < (averaging + 2) * cycle


def test_a_simulated_day_of_the_default_bench_is_jumped_not_scanned():
    """24 virtual hours cost a handful of scans, not the 8.64 million a scan-by-scan day would run: counted, not
    timed (the day's wall time is a benchmark's figure: benchmarks/run.py "Virtual time")."""
    emulator = build_emulator(load_profile(EMULATOR_BENCH), EPOCH)
    emulator.advance(86400)
    emulator.scan()
    assert emulator.memory.read("R4131", 3) == [29, 2, 24]  # the RTC crossed into the leap day
    stepped = round(emulator.now / emulator.scan_time)
    assert emulator.scans_represented == stepped  # the scans a PLC would have run, counted (the ladder's counter)…
    assert emulator.scans < stepped / 1000, f"{emulator.scans} scans run for a day"  # …under a thousandth run


def pid_profile():
    """The default bench's temperature modules with FUN86 on points 0–3 and the thermal plant (if landed)."""
    pytest.importorskip("hil.families.fbs.sim.models.fun86", reason="the FUN86 model has not landed")
    pytest.importorskip("hil.families.fbs.sim.models.plant", reason="the plant model has not landed")
    base = load_profile(EMULATOR_BENCH)
    return profile_from_dict({"bench": {"name": "ff-pid"}, "rtc": {"chip": 3}, "temperature": base.areas["temperature"],
                              "pid": {"en": "M0", "sn": 0, "zn": 4, "yn": "Y0", "sv": "R1000", "os": "R1040",
                                      "pr": "R1080", "ir": "R1120", "dr": "R1160", "or": "R1200", "wr": "R1240"},
                              "plant": {}})


@pytest.mark.parametrize("seconds", [3.7, 95.0, 300.0])
def test_jump_equals_stepping_with_pid_and_plant(seconds):
    profile = pid_profile()
    stepped, jumped = build_emulator(profile, EPOCH), build_emulator(profile, EPOCH)
    for emu in (stepped, jumped):
        emu.memory.set("M0", 1)  # FUN86 EN
        emu.memory.set("R4012", 0x000F)  # PID on points 0–3
        for p in range(4):
            emu.memory.set(f"R{1000 + p}", 600 + 50 * p)  # SV 60.0 … 75.0 °C
        emu.scan()  # the request that wrote them is followed by a scan
    for _ in range(round(seconds / stepped.scan_time)):
        stepped.scan()
    jumped.advance_to(stepped.now)
    assert jumped.now == stepped.now
    for first, count in (("R3020", 32), ("R1200", 4), ("R1240", 4), ("R4128", 8)):
        assert jumped.memory.read(first, count) == stepped.memory.read(first, count), first
    assert jumped.memory.read("Y0", 4) == stepped.memory.read("Y0", 4)


# -- FUN86's own events, change by change ---------------------------------------------------------------------------
# A jump must land on every scan at which FUN86's outputs can change (Model.next_event): the outputs' and alarm bits'
# every change, at the very scan stepping makes it, not only the state at the end (a final scan recomputes the Y and
# heater-loop bits from the clock, and would hide a wake-up missed on the way).  Without the thermal plant, so that
# FUN86 schedules its PWM edges itself (pwm_exact off).

#: where the compared FUN86 box lives (fun86_profile): its outputs, OR words, WR block and ALM
FUN86_OPERANDS = {"en": "M0", "alm": "M101", "sn": 0, "yn": "Y0", "sv": "R1000", "os": "R1040", "pr": "R1080",
                  "ir": "R1120", "dr": "R1160", "or": "R1200", "wr": "R1240"}
#: the 16TC modules' first round of every point (6 s at the normal rate): FUN86 waits for it
FIRST_ROUND = 6.5


def fun86_profile(zn: int):
    """The default bench's temperature modules (fixed PVs: point p at 25.0 + 0.3 p °C) and one FUN86 box on points
    0 … zn − 1, no plant."""
    pytest.importorskip("hil.families.fbs.sim.models.fun86", reason="the FUN86 model has not landed")
    base = load_profile(EMULATOR_BENCH)
    return profile_from_dict({"bench": {"name": "ff-fun86"}, "rtc": {"chip": 3},
                              "temperature": base.areas["temperature"], "pid": dict(FUN86_OPERANDS, zn=zn)})


def started_pair(zn: int, before_en: dict[str, int], gains: dict[str, int]) -> tuple[Emulator, Emulator]:
    """Two identical emulators with the FUN86 box running, heating (H/C = M1 = 1): every point measured, ``before_en``
    written (R4005 is latched on EN's rising edge), EN on, then ``gains`` over the first execution's defaults."""
    pair = build_emulator(fun86_profile(zn), EPOCH), build_emulator(fun86_profile(zn), EPOCH)
    for emu in pair:
        emu.advance(FIRST_ROUND)
        for writes in (dict(before_en, M0=1, M1=1), gains):
            for name, value in writes.items():
                emu.memory.set(name, value)
            emu.scan()  # the request that wrote them is followed by a scan
    return pair


def watched(emu: Emulator, zn: int) -> tuple[int, ...]:
    mem = emu.memory
    return (*mem.read("Y0", zn), *mem.read("R1200", zn), *mem.read("R1240", 4), mem.get("M101"))


def changes(emu: Emulator, run: Callable[[], object], zn: int) -> list[tuple[float, tuple[int, ...]]]:
    """(virtual time, watched memory) at every scan of ``run()`` that changed the watched memory."""
    log: list[tuple[float, tuple[int, ...]]] = []

    def observe(e: Emulator) -> None:
        state = watched(e, zn)
        if not log or log[-1][1] != state:
            log.append((e.now, state))
    emu.observers.append(observe)
    try:
        run()
    finally:
        emu.observers.remove(observe)
    return log


def assert_jump_changes_as_stepping(stepped: Emulator, jumped: Emulator, seconds: float, zn: int) -> None:
    """Stepping ``seconds`` scan by scan and jumping them change FUN86's outputs at the same scans, to the same
    values — and the jump did jump (scanned a fraction of the span)."""
    steps = round(seconds / stepped.scan_time)
    stepped_log = changes(stepped, lambda: [stepped.scan() for _ in range(steps)], zn)
    scans = jumped.scans
    jumped_log = changes(jumped, lambda: jumped.advance_to(stepped.now), zn)
    assert len(stepped_log) > 1, "nothing changed: the scenario shows nothing"
    for (t_step, step), (t_jump, jump) in zip(stepped_log, jumped_log):
        # the same scan — or the next, for an event due exactly at a scan: stepping adds the scan times up as floats
        # (9.509999…), a jump lands on the grid (9.51), and a deadline there falls on either side
        assert jump == step and abs(t_jump - t_step) < 1.5 * stepped.scan_time, \
            f"changed at {t_jump:.4f} s to {jump} jumping, at {t_step:.4f} s to {step} stepping"
    assert len(jumped_log) == len(stepped_log)
    assert jumped.scans - scans < steps / 4, f"{jumped.scans - scans} scans run for {steps}"


def test_a_pwm_edge_between_wake_ups_is_a_wake_up():
    """One point at a partial output: its Y goes off at the ON time's end inside each PWM period (4 s), between the
    PID steps (2 s) and the measurements (0.375 s): no other event wakes the engine for it."""
    stepped, jumped = started_pair(1, {"R4005": 0x0201, "R1000": 262, "R1040": 5},
                                   {"R1080": 50, "R1120": 0, "R1160": 0})
    assert_jump_changes_as_stepping(stepped, jumped, 12.0, 1)


def test_a_prealarm_count_in_progress_is_scanned_scan_by_scan():
    """PV ≥ R4008 from the first scan: the warning bit rises after 10 consecutive scans, in stepping and jumping
    alike (the count needs every scan, not only the measurements' and PID steps')."""
    stepped, jumped = started_pair(4, {"R4008": 200, "R1000": 300, "R1040": 20}, {})
    assert_jump_changes_as_stepping(stepped, jumped, 4.0, 4)


def test_a_heater_loop_deadline_is_a_wake_up():
    """Output 100 % (≥ R4006 = 50 %) with PV far below SV: the heater-loop warning at R4007 = 3 s after the first
    PID step, between the PID steps (2 s), the PWM cycles (4 s) and the measurements (0.375 s)."""
    stepped, jumped = started_pair(2, {"R4005": 0x0201, "R4006": 50, "R4007": 3, "R1000": 1000, "R1001": 1000,
                                       "R1040": 10, "R1041": 10}, {})
    assert_jump_changes_as_stepping(stepped, jumped, 5.0, 2)
