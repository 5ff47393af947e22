"""Edge cases of the temperature, FUN86 and plant models against golden records (tests/test_model_golden.py), from a
review of the (since deleted) compiled kernel: timing codes, R4006/R4007/R4008 edges, gains, negative SV/OS/PV,
Sn ≠ 0, settable/ERR/EN-off instances next to running ones, points outside the measured modules, fitted modules the
table does not measure, 64-bit seeds, long runs, requests right before a jump, stepping on after a long jump, scan
times, the clock's elements shared with the PID's, models in another order.
"""

from __future__ import annotations

import pytest

from hil.bench.profile import load_profile, profile_from_dict
from hil.families.fbs.sim.build import add_pid_models, build_emulator
from hil.families.fbs.sim.models.fun86 import Fun86Model
from hil.families.fbs.sim.models.plant import ThermalPlant
from hil.families.fbs.sim.models.rtc import RtcModel
from hil.families.fbs.sim.models.temperature import Fixed, Ramp, TemperatureModel
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.temperature import MODULE_BY_CODE, parse_temperature
from tests.conftest import EMULATOR_BENCH
from tests.test_model_golden import (
    EPOCH,
    FULL_MODULES,
    GOLDEN_REFERENCE,
    PID_32,
    against_golden,
    full_plc,
    profile,
    start,
)

MODULES = {m.name: m for m in MODULE_BY_CODE.values()}
SV_1500 = {f"R{1000 + p}": 1500 for p in range(32)}


def plc(modules=FULL_MODULES, pid=PID_32, plant=None, emulator=None, **temperature):
    """full_plc with any [temperature] keys, [pid], [plant] and [emulator]."""
    def build():
        prof = profile(modules, plant=plant or {}, pid=pid, **temperature)
        if emulator:
            data = {"bench": {"name": "kernel"}, "rtc": {"chip": 3, "crystal_ppm": 12.5}, "emulator": emulator,
                    "temperature": prof.areas["temperature"], "pid": pid, "plant": plant or {}}
            prof = profile_from_dict(data)
        return build_emulator(prof, EPOCH)
    return build


def fitted_plc(fitted, pid=PID_32, plant=None):
    """full_plc whose physically fitted modules differ from the table (build_emulator, with ``fitted=``)."""
    def build():
        prof = profile(FULL_MODULES, plant=plant or {}, pid=pid)
        emu = Emulator(scan_time=prof.emulator.scan_time_ms / 1000, seed=prof.emulator.seed)
        emu.add_model(RtcModel(chip=3, crystal_ppm=12.5, start=EPOCH))
        emu.add_model(TemperatureModel(parse_temperature(prof.areas["temperature"]), fitted=fitted))
        add_pid_models(emu, prof)
        return emu
    return build


# =====================================================================================================================
# Found by the review (each failed before its fix)
# =====================================================================================================================
def test_a_fitted_module_the_table_does_not_match():
    """Module 7 of the table is a 2TC but a 6RTD is fitted: its points are never measured and its schedule stands
    still.  With R4008 reachable, FUN86 asks for a scan at the next measurement — of the measured modules only, in
    Python (TemperatureModel._active) as in C.  (Before: Python took every fitted module's, so a stale one kept it
    scanning every 10 ms.)"""
    fitted = [MODULES["6TC"]] * 4 + [MODULES["2TC"]] * 3 + [MODULES["6RTD"]]

    def drive(emu) -> None:
        start(emu, sv=SV_1500, R4008=1400)
        emu.advance(60)
    against_golden(fitted_plc(fitted), drive)


def test_the_ladder_shortens_the_table():
    """The realistic way there: a request drops the last two modules from the table (SR+1 = 6).  Modules 6 and 7
    stay fitted but are no longer measured: their schedules stand still and must not look due."""
    def drive(emu) -> None:
        start(emu, sv=SV_1500, R4008=1400)
        emu.advance(20)
        emu.service(lambda mem: mem.set("R3001", 6))
        emu.advance(40)
    against_golden(full_plc(), drive)


def test_a_fitted_module_beyond_the_table():
    """The same through a fitted module the table does not list at all (k ≥ the table's module count)."""
    fitted = [MODULES["6TC"]] * 4 + [MODULES["2TC"]] * 4 + [MODULES["2TC"]]

    def drive(emu) -> None:
        start(emu, sv=SV_1500, R4008=1400)
        emu.advance(60)
    against_golden(fitted_plc(fitted), drive)


@pytest.mark.parametrize("readings", ["R4120", "D4030"])
def test_readings_over_the_rtc_registers(readings):
    """The readings block over R4128–R4135 (the clock's read-out) or D4053/D4054: the RTC model rewrites them every
    scan (and re-anchors on a new D4054): the clock's registers meet the PID's."""
    def drive(emu) -> None:
        start(emu, sv=SV_1500)
        emu.advance(120)
    against_golden(plc(readings=readings), drive)


@pytest.mark.parametrize("alm", ["M1952", "M1953", "M1954"])
def test_alm_on_an_rtc_bit(alm):
    """ALM of the running instance on M1952 (RTC hold), M1953 (±30 s) or M1954 (rewritten by every RTC scan), and
    ALM toggling between requests: the clock sees each edge."""
    def drive(emu) -> None:
        start(emu, sv={f"R{1000 + p}": 250 for p in range(32)}, enable=1, **{f"R{1040 + p}": 7 for p in range(32)})
        emu.advance(305)  # (ends with ALM = 0: M1954 then shows the RTC's 1)
    against_golden(plc(pid=dict(PID_32, alm=alm), plant={"noise": 1.0, "gain": 0.0}), drive)


@pytest.mark.parametrize("seed", [2**53 + 1, 1234567890123456789, -(2**62) - 3, 2**63 - 1])
def test_a_seed_beyond_2_to_the_53(seed):
    """``[emulator] seed`` is any TOML int: the noise index takes it modulo 2^64 exactly (a float64 would round it
    beyond 2^53 and draw other normals than ``seed * K & MASK``)."""
    def drive(emu) -> None:
        start(emu, sv=SV_1500)
        emu.advance(60)
    against_golden(plc(plant={"noise": 0.5}, emulator={"scan_time_ms": 10, "seed": seed}), drive)


def test_models_in_another_order():
    """An emulator whose plant scans before FUN86 (models added in another order) integrates the previous scan's
    waveform."""
    def build():
        emu = full_plc()()
        fun86, plant = emu.model(Fun86Model), emu.model(ThermalPlant)
        i, j = emu.models.index(fun86), emu.models.index(plant)
        emu.models[i], emu.models[j] = plant, fun86
        return emu

    def drive(emu) -> None:
        start(emu, sv=SV_1500)
        emu.advance(120)
    against_golden(build, drive)


# =====================================================================================================================
# Edges of the arithmetic
# =====================================================================================================================
@pytest.mark.parametrize("r4005", [0x0000, 0x0101, 0x0505, 0x00FF, 0xFF00, 0x0500, 0x0005, 0x0302, 0x0203])
def test_pid_interval_and_pwm_codes(r4005):
    """R4005 latched at the EN edge: 1–32 s intervals and PWM periods, codes ≥ 5 (incl. 0xFF) = 32 s."""
    def drive(emu) -> None:
        start(emu, sv=SV_1500, R4005=r4005, R4008=1450)
        emu.advance(240)
    against_golden(full_plc(noise=0.2, tau=60.0), drive)


@pytest.mark.parametrize("r4006, r4007, r4008", [(0, 0, 0), (100, 1, 65535), (65535, 65535, 0), (0, 65535, 1),
                                                  (100, 0, 100), (1, 5, 250), (99, 30, 32767), (0, 1, 32768)])
def test_heater_loop_and_prealarm_edge_values(r4006, r4007, r4008):
    def drive(emu) -> None:
        start(emu, sv=SV_1500, R4006=r4006, R4007=r4007, R4008=r4008)
        emu.advance(150)
    against_golden(full_plc(gain=50.0, tau=60.0), drive)


@pytest.mark.parametrize("md, kc, ki, td", [(1, 110, 17, 50), (0, 110, 0, 50), (1, 110, 0, 0), (0, 65535, 65535, 65535),
                                             (1, 65535, 1, 0), (0, 0, 0, 0), (0, 1, 65535, 0), (1, 3, 100, 1000)])
def test_gains_md_ki0_td0_and_a_huge_kc(md, kc, ki, td):
    pid = dict(PID_32, md=md)

    def drive(emu) -> None:
        start(emu, sv={f"R{1000 + p}": 300 + 5 * p for p in range(32)}, R4005=0x0100,
              **{f"R{1080 + p}": kc for p in range(32)}, **{f"R{1120 + p}": ki for p in range(32)},
              **{f"R{1160 + p}": td for p in range(32)}, **{f"R{1040 + p}": 15 for p in range(32)})
        emu.advance(200)
    against_golden(plc(pid=pid, plant={"noise": 0.5, "tau": 40.0}), drive)


@pytest.mark.parametrize("heating", [True, False])
def test_negative_sv_os_and_pv_below_zero(heating):
    """A freezer: ambient −60 °C, PVs below zero, negative set points, a negative deviation (never normal) on some
    points, zero on others; heating and cooling mode."""
    sv = {f"R{1000 + p}": (-450 - 10 * p) & 0xFFFF for p in range(32)}
    os = {f"R{1040 + p}": (-5 if p % 3 == 0 else 0 if p % 3 == 1 else 20) & 0xFFFF for p in range(32)}

    def drive(emu) -> None:
        start(emu, sv=sv, heating=heating, R4008=0, R4006=0, R4007=20, **os)
        emu.advance(200)
    against_golden(full_plc(ambient=-60.0, gain=40.0, tau=50.0, noise=0.3), drive)


def test_negative_pv_with_fahrenheit_fast_averaging():
    def drive(emu) -> None:
        start(emu, sv={f"R{1000 + p}": (-400) & 0xFFFF for p in range(32)}, R4008=65000)
        emu.advance(150)
    against_golden(plc(plant={"ambient": -80.0, "gain": 60.0, "tau": 30.0, "noise": 0.4}, unit="F", rate="fast",
                       averaging=8), drive)


@pytest.mark.parametrize("sensor", ["B", "T", "R"])
def test_sensor_range_clamps_with_integer_limits(sensor):
    """Sensor limits are ints (B: 350–1800 °C clamps the 25 °C plant to the int 350)."""
    modules = [{"type": "6TC", "sensor": sensor}] * 4 + [{"type": "2TC", "sensor": sensor}] * 4

    def drive(emu) -> None:
        start(emu, sv=SV_1500, R4008=1000)
        emu.advance(120)
    against_golden(plc(modules=modules, plant={"gain": 500.0, "tau": 40.0}, averaging=4), drive)


def default_bench(plant=None):
    """The default bench's three instances (zone-a 0–9, zone-b Md 1 12–31, err-check settable) on a waved plant."""
    base = load_profile(EMULATOR_BENCH)

    def build():
        prof = profile_from_dict({"bench": {"name": "kernel"}, "rtc": {"chip": 3, "crystal_ppm": 12.5},
                                  "temperature": {**base.areas["temperature"], "reference": GOLDEN_REFERENCE},
                                  "pid": base.areas["pid"],
                                  "plant": plant or {}})
        return build_emulator(prof, EPOCH)
    return build


@pytest.mark.parametrize("sn, zn", [(5, 3), (31, 1), (0, 32), (20, 12)])
def test_a_settable_instance_with_sn_not_zero_next_to_the_others(sn, zn):
    """err-check (Sn/Zn from R850/R851) running on points shared with zone-a/zone-b."""
    def drive(emu) -> None:
        start(emu, sv={f"R{100 + b}": 600 for b in range(10)})
        start(emu, en="M2", hc="M3", heating=False, sv={f"R{400 + b}": 300 for b in range(20)})
        start(emu, en="M4", hc="M5", sv={f"R{600 + b}": 400 + b for b in range(32)}, R850=sn, R851=zn,
              R4008=700)
        emu.advance(200)
    against_golden(default_bench(), drive)


@pytest.mark.parametrize("sn, zn", [(-1, 3), (30, 3), (0, 0), (0, 33)])
def test_an_err_instance_next_to_running_ones(sn, zn):
    """err-check EN on with bad Sn/Zn (ERR) while zone-a and zone-b run; also after having run with good ones."""
    def drive(emu) -> None:
        start(emu, sv={f"R{100 + b}": 600 for b in range(10)})
        start(emu, en="M2", hc="M3", sv={f"R{400 + b}": 500 for b in range(20)})
        start(emu, en="M4", hc="M5", sv={f"R{600 + b}": 400 for b in range(32)}, R850=2, R851=4)
        emu.advance(30)
        emu.service(lambda mem: (mem.set("R850", sn & 0xFFFF), mem.set("R851", zn & 0xFFFF)))
        emu.advance(120)
        assert emu.memory.get("M104") == 1
    against_golden(default_bench(), drive)


def test_en_off_instances_that_ran_next_to_a_running_one():
    def drive(emu) -> None:
        start(emu, sv={f"R{100 + b}": 600 for b in range(10)})
        start(emu, en="M2", hc="M3", sv={f"R{400 + b}": 500 for b in range(20)})
        start(emu, en="M4", hc="M5", R850=0, R851=32)
        emu.advance(40)
        emu.service(lambda mem: (mem.set("M2", 0), mem.set("M4", 0)))
        emu.advance(150)
    against_golden(default_bench(), drive)


def test_instance_points_beyond_the_tables_measured_points():
    """One 6TC measured (points 0–5); the instance controls 0–31: points 6–31 keep their reading."""
    def drive(emu) -> None:
        start(emu, sv=SV_1500)
        emu.service(lambda mem: mem.write("R3026", [1000 + p for p in range(26)]))  # readings of unmeasured points
        emu.advance(60)
    against_golden(plc(modules=[{"type": "6TC", "sensor": "K"}]), drive)


def test_a_module_mismatch_without_a_possible_prealarm():
    """The mismatched module of test_divergence_a, but no reading can reach R4008: the stale ``_next`` only
    matters through ``measurements``."""
    fitted = [MODULES["6TC"]] * 4 + [MODULES["2TC"]] * 3 + [MODULES["6RTD"]]

    def drive(emu) -> None:
        start(emu, sv=SV_1500)
        emu.advance(300)
    against_golden(fitted_plc(fitted), drive)


def test_points_not_installed_broken_and_disabled_mixed():
    def build():
        emu = full_plc(noise=0.2)()
        tm = emu.model(TemperatureModel)
        tm.open(7)
        tm.open(20)
        return emu

    def drive(emu) -> None:
        start(emu, sv=SV_1500, enable=0xFFFFFFFF & ~(1 << 9) & ~(1 << 20), R4010=0xFFFF & ~(1 << 3) & ~(1 << 9),
              R4011=0xFFFF & ~(1 << 15), R4008=1200)
        emu.advance(120)
        emu.model(TemperatureModel).repair(7)
        emu.service(lambda mem: mem.set("R4010", 0xFFFF))
        emu.advance(120)
    against_golden(build, drive)


def test_ramps_fixed_sources_and_no_noise():
    def build():
        emu = full_plc(noise=0.0)()
        tm = emu.model(TemperatureModel)
        tm.set_source(4, Ramp(200.0, -0.5, low=-20.0))
        tm.set_source(5, Ramp(-30.0, 0.25, high=160.0))
        tm.set_source(6, Fixed(149.95))
        tm.set_source(7, Fixed(-0.05))
        tm.set_source(8, Ramp(0.0, 0.0))
        return emu

    def drive(emu) -> None:
        start(emu, sv=SV_1500, R4008=1500)
        emu.advance(240)
    against_golden(build, drive)


@pytest.mark.parametrize("scan_ms", [1, 7, 50])
def test_other_scan_times(scan_ms):
    def drive(emu) -> None:
        start(emu, sv=SV_1500, R4008=1450, R4005=0x0100)
        emu.advance(100)
    against_golden(plc(plant={"noise": 0.3, "tau": 60.0}, emulator={"scan_time_ms": scan_ms, "seed": 7}), drive)


@pytest.mark.parametrize("seed", [0, 1, -1, 2**53, -(2**53), 987654321])
def test_seeds_within_float64_precision(seed):
    def drive(emu) -> None:
        start(emu, sv=SV_1500)
        emu.advance(60)
    against_golden(plc(plant={"noise": 0.5}, emulator={"scan_time_ms": 10, "seed": seed}), drive)


def test_two_virtual_hours_of_a_small_plc():
    """A small PLC (one 2TC, one instance on both points, 32 s interval) for 2 virtual hours (a scan at each of
    its measurements: 24 hours took a minute)."""
    pid = dict(PID_32, zn=2)

    def drive(emu) -> None:
        start(emu, sv={"R1000": 1200, "R1001": 800}, R4005=0x0505)
        emu.advance(7200)
    against_golden(plc(modules=[{"type": "2TC", "sensor": "K"}], pid=pid, plant={"noise": 0.1}), drive)


def test_pid_starting_days_after_power_on():
    pid = dict(PID_32, zn=2)

    def drive(emu) -> None:
        emu.advance(5 * 86400 + 0.37)
        start(emu, sv={"R1000": 1200, "R1001": 800}, R4005=0x0100, R4008=1150)
        emu.advance(600)
    against_golden(plc(modules=[{"type": "2TC", "sensor": "K"}], pid=pid, plant={"noise": 0.1}), drive)


def test_requests_that_change_things_right_before_each_jump():
    """Each jump starts right after a request that changed SV, OS, H/C, gains, R4006–R4008, the enable mask, a
    reading, an OR (even above 16383), or a source/sensor (outside a request)."""
    changes = [
        lambda mem: mem.write("R1000", [1300] * 16),
        lambda mem: mem.set("M1", 0),
        lambda mem: mem.set("M1", 1),
        lambda mem: mem.write("R1080", [65535] * 8),
        lambda mem: mem.write("R1120", [0] * 8),
        lambda mem: mem.set("R4008", 1000),
        lambda mem: mem.set("R4006", 0),
        lambda mem: mem.set("R4012", 0x00FF),
        lambda mem: mem.write("R1200", [65535, 16384, 0, 9000]),
        lambda mem: mem.write("R1000", [300] * 32),
        lambda mem: mem.set("R4013", 0x0000),
        lambda mem: mem.write("R3020", [0xFFFF, 0x8000, 0x7FFF]),
    ]

    def drive(emu) -> None:
        start(emu, sv=SV_1500, R4005=0x0203)
        emu.advance(20)
        for n, change in enumerate(changes):
            emu.service(change)
            if n == 4:
                emu.model(TemperatureModel).set_source(3, Ramp(100.0, 0.3))
            if n == 6:
                emu.model(TemperatureModel).open(2)
            emu.advance(9.13 + n)
    against_golden(full_plc(noise=0.3, tau=50.0), drive)


def test_stepping_on_after_a_long_jump():
    """After a long jump, short steps and requests (stale caches — the plant's memo, the temperature model's quiet
    block, the waveforms — would show there)."""
    def drive(emu) -> None:
        start(emu, sv=SV_1500, R4008=1480, R4005=0x0102)
        emu.advance(120)
        for n in range(6):
            emu.advance(3.3)
            emu.service(lambda mem, n=n: mem.write("R1000", [1500 - 20 * n] * 32))
            emu.model(ThermalPlant).temperature(0, emu.now + 5.0)  # fill the memo
            emu.advance(4.1)
    against_golden(full_plc(noise=0.2, tau=60.0), drive)


def test_cooling_and_heating_instances_on_one_plant_with_averaging():
    def drive(emu) -> None:
        start(emu, sv={f"R{100 + b}": 900 for b in range(10)})
        start(emu, en="M2", hc="M3", heating=False, sv={f"R{400 + b}": 200 for b in range(20)}, R4008=880)
        emu.advance(240)
    base = load_profile(EMULATOR_BENCH)
    area = dict(base.areas["temperature"], averaging=8, unit="F", reference=GOLDEN_REFERENCE)

    def build():
        return build_emulator(profile_from_dict({"bench": {"name": "kernel"}, "temperature": area,
                                                 "pid": base.areas["pid"], "plant": {"noise": 0.5}}), EPOCH)
    against_golden(build, drive)
