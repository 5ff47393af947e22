"""Fast-forward must not change results: jumping virtual time equals stepping it scan by scan."""

from __future__ import annotations

import datetime as dt

import pytest

from hil.bench.profile import load_profile, profile_from_dict
from hil.families.fbs.sim.build import build_emulator
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
