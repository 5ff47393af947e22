"""FUN86 and the thermal plant in the emulator, the [pid]/[plant] profile sections, and plc.pid's trace."""

from __future__ import annotations

import datetime as dt
import tomllib

import pytest

from hil.bench.profile import load_profile, profile_from_dict
from hil.core.errors import ProfileError
from hil.families.fbs.bench import Bench
from hil.families.fbs.pid import PidInstance, parse_pid
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.models.fun86 import Fun86Model
from hil.families.fbs.sim.models.plant import ThermalPlant
from tests.conftest import EMULATOR_BENCH, EMULATOR_TARGETS

EPOCH = dt.datetime(2024, 5, 1, 8, 0, 0)


# -- [pid] --------------------------------------------------------------------------------------------------------
def test_an_empty_pid_section_is_the_manuals_example_program():
    (inst,) = parse_pid({}).instances
    assert inst == PidInstance()
    assert (str(inst.en), str(inst.hc), str(inst.err), str(inst.alm), str(inst.yn)) == ("M0", "M1", "M100", "M101",
                                                                                         "Y30")
    assert (inst.sn, inst.zn, str(inst.sv), str(inst.or_), str(inst.wr)) == (0, 10, "R100", "R200", "R300")


@pytest.mark.parametrize("section,words", [
    ({"yn": "M30"}, "not a Y output"),
    ({"err": "R5"}, "not a bit"),
    ({"sv": "R4100"}, "not a FUN86 register operand"),
    ({"sv": 100}, "element name"),
    ({"zn": 0}, "1–32"),
    ({"sn": 30, "zn": 5}, r"Sn \+ Zn = 35"),
    ({"md": 2}, "0–1"),
    ({"colour": "red"}, "unknown key"),
    ({"os": "R105"}, "overlaps"),  # Sv R100 + 10 points reaches R109
    ({"yn": "Y250"}, "runs past Y255"),
    ({"sn_register": "R500"}, "go together"),
    ({"instances": [{"name": "a"}, {"name": "a", "en": "M9"}]}, "names must differ"),
    ({"instances": [{"name": "a"}], "en": "M0"}, "both instances and instance keys"),
    ({"instances": [{"name": "a"}, {"name": "b", "sn": 5, "zn": 3, "sv": "R1000", "os": "R1010", "pr": "R1020",
                                    "ir": "R1030", "dr": "R1040", "or": "R1050", "wr": "R1060", "yn": "Y100",
                                    "err": "M200", "alm": "M201"}]}, "both control points 5–7"),
    ({"instances": [{"name": "a"}, {"name": "b", "sn": 20, "zn": 3, "wr": "R305", "sv": "R1000", "os": "R1010",
                                    "pr": "R1020", "ir": "R1030", "dr": "R1040", "or": "R1050", "yn": "Y100",
                                    "err": "M200", "alm": "M201"}]}, "b.wr"),
    ({"en": "M100"}, "an output of FUN86"),
])
def test_bad_pid_sections_are_refused_with_the_reason(section, words):
    with pytest.raises(ProfileError, match=words):
        profile_from_dict({"bench": {"name": "x"}, "pid": section})


def test_bad_plant_sections_are_refused():
    for section, words in (({"tau": 0}, "tau"), ({"wind": 1}, "unknown key"), ({"points": {"40": {}}}, "0–31"),
                           ({"noise": "lots"}, "noise")):
        with pytest.raises(ProfileError, match=words):
            profile_from_dict({"bench": {"name": "x"}, "plant": section})


def test_the_emulator_bench_describes_three_fun86_boxes_and_a_plant():
    profile = load_profile(EMULATOR_BENCH)
    config = parse_pid(profile.areas["pid"])
    assert [i.name for i in config.instances] == ["zone-a", "zone-b", "err-check"]
    emulator = build_emulator(profile, EPOCH)
    assert [m.name for m in emulator.models] == ["rtc", "temperature", "fun86", "plant"]


# -- the model ------------------------------------------------------------------------------------------------------
@pytest.fixture
def emu():
    return build_emulator(load_profile(EMULATOR_BENCH), EPOCH)


def _run(emu, sv=None, gains=None):
    m = emu.memory
    if sv is not None:
        m.write("R100", sv)
    m.set("M0", 1)
    m.set("M1", 1)
    emu.scan()
    if gains:
        m.write("R120", [gains[0]] * 10)
        m.write("R130", [gains[1]] * 10)
        m.write("R140", [gains[2]] * 10)


def test_nothing_happens_before_every_fitted_point_is_measured(emu):
    _run(emu, sv=[2000])
    assert emu.memory.read("R120", 3) == [110, 110, 110], "defaults load at the first execution"
    emu.advance(3.0)  # a 16TC needs 6 s for all its points
    assert emu.memory.get("R200") == 0 and emu.memory.read("R300", 4) == [0, 0, 0, 0]
    emu.advance(4.0)
    assert emu.memory.get("R200") > 0 and emu.memory.get("Y30") == 1


def test_r4005_takes_effect_only_after_en_goes_0_then_1(emu):
    _run(emu)
    model = emu.model(Fun86Model)
    assert (model.states[0].interval, model.states[0].pwm) == (4.0, 2.0)
    emu.memory.set("R4005", 0x0300)  # PWM 8 s, PID every 1 s
    emu.advance(1.0)
    assert (model.states[0].interval, model.states[0].pwm) == (4.0, 2.0)
    emu.memory.set("M0", 0)
    emu.scan()
    emu.memory.set("M0", 1)
    emu.scan()
    assert (model.states[0].interval, model.states[0].pwm) == (1.0, 8.0)
    emu.memory.set("R4005", 0x0909)
    emu.memory.set("M0", 0)
    emu.scan()
    emu.memory.set("M0", 1)
    emu.scan()
    assert (model.states[0].interval, model.states[0].pwm) == (32.0, 32.0)


def test_pwm_is_on_for_or_over_16383_of_each_period(emu):
    emu.model(ThermalPlant).set_fault("heater_open", 0, True)  # PV stays put: the output stays put
    emu.advance(7.0)
    pv = emu.memory.get("R3020")
    _run(emu, sv=[pv + 4096], gains=(2, 0, 0))  # output 2 × 4096 = 8192 ≈ 50 %
    emu.advance(8.0)
    out = emu.memory.get("R200")
    assert abs(out - 8192) <= 4
    on = total = 0
    for _ in range(1000):  # 10 s = 5 PWM periods, every scan
        emu.scan()
        on += emu.memory.get("Y30")
        total += 1
    assert abs(on / total - out / 16383) < 0.02


def test_pv_comes_from_r4004_when_r4003_is_a55a(emu):
    _run(emu, sv=[1000] * 10, gains=(1, 0, 0))
    m = emu.memory
    m.write("R110", [10] * 10)
    emu.advance(7.0)
    assert m.get("R300") == 0  # PV 25 °: none of SV 100.0 ± 1.0
    m.write("R1000", [1000] * 10)  # a ladder's own PVs at R1000…
    m.write("R4003", [0xA55A, 11000])
    emu.scan()
    assert m.get("R300") == 0x03FF
    m.set("R4003", 0)
    emu.scan()
    assert m.get("R300") == 0


def test_a_disabled_point_gets_output_0_and_no_bits(emu):
    _run(emu, sv=[2000] * 10)
    emu.advance(10.0)
    m = emu.memory
    assert m.get("R200") > 0 and m.get("M101") == 1
    m.set("R4012", 0xFFFE)
    emu.advance(5.0)
    assert m.get("R200") == 0 and m.get("Y30") == 0
    assert m.get("R300") & 1 == 0 and m.get("R302") & 1 == 0


def test_err_and_nothing_else_for_bad_sn_zn(emu):
    m = emu.memory
    m.write("R850", [31, 2])
    m.set("M4", 1)
    emu.scan()
    assert m.get("M104") == 1 and m.read("R680", 3) == [0, 0, 0]  # no first execution either
    m.write("R850", [0, 1])
    emu.scan()
    assert m.get("M104") == 0 and m.get("R680") == 110


def test_ssr_short_heats_whatever_the_output(emu):
    plant = emu.model(ThermalPlant)
    plant.set_fault("ssr_short", 5, True)
    emu.advance(300.0)
    assert emu.memory.get("R3025") > 1500  # ≈ 25 + 300 × (1 − e⁻¹) ≈ 215 °C
    assert emu.memory.get("R3024") < 300
    with pytest.raises(ValueError, match="no heater"):
        plant.set_fault("heater_open", 10, True)


def test_the_plant_dead_time_delays_the_heating(emu):
    plant = emu.model(ThermalPlant)
    plant.set_fault("ssr_short", 2, True)
    emu.scan()
    start = emu.now
    assert plant.temperature(2, start + 1.9) == pytest.approx(25.0)  # dead time 2 s
    assert plant.temperature(2, start + 12.0) > 25.0 + 300 * (1 - 2.718 ** (-9.9 / 300)) * 0.99


@pytest.mark.parametrize("seconds", [20.0, 400.0])
def test_jumping_equals_stepping_with_the_pid_running(seconds):
    """Jumps land on the scan stepping would take (FUN86 rounds its events up to the scan grid), so PID samples,
    PWM edges and PVs are seen at the same scans.  What is left is float rounding of the clock, which a bang-bang
    loop with dead time amplifies chaotically — hence a plant without noise or dead time here, and 0.2 °."""
    data = tomllib.loads(EMULATOR_BENCH.read_text())
    data["plant"].update(noise=0.0, dead_time=0.0)
    profile = profile_from_dict(data)
    stepped, jumped = build_emulator(profile, EPOCH), build_emulator(profile, EPOCH)
    for emu in (stepped, jumped):
        _run(emu, sv=[800, 600, 0, 1200] + [0] * 6)
        emu.memory.write("R110", [100] * 10)
    for _ in range(round(seconds / stepped.scan_time)):
        stepped.scan()
    jumped.advance_to(stepped.now)
    assert jumped.scans < stepped.scans / 5
    a, b = stepped.memory.read("R3020", 10), jumped.memory.read("R3020", 10)
    assert all(abs(x - y) <= 2 for x, y in zip(a, b)), (a, b)
    assert stepped.memory.read("R300", 4) == jumped.memory.read("R300", 4)


def _in_band_without_heating(emu):
    """Zone-a running with SV = PV, a wide band and no heating (PVs stay put), every point measured."""
    m = emu.memory
    m.write("R4012", [0xFFFF, 0xFFFF])
    emu.advance(20)
    emu.scan()
    m.write("R100", m.read("R3020", 10))
    m.write("R110", [1000] * 10)
    m.write("R120", [1] * 10)
    m.write("R130", [0] * 10)
    m.write("R140", [0] * 10)
    _run(emu)
    emu.advance(10)
    assert min(m.read("R3020", 10)) >= 100  # R4008 = 100 is under every PV


def test_a_prealarm_count_never_runs_ahead_of_the_scans_after_a_jump_off_the_grid(emu):
    """A jump clipped at a request's time lands between two grid points and the scans go on from there: a reading
    taken in the next scan's interval was first seen by that scan, not by a 'skipped' grid point it had already
    passed — counting it twice put one point's pre-alarm count a scan ahead (a warning after 9 scans on the scan
    counter of `hil emulate` that had fallen behind).  Every count is at most the scans since R4008 went under
    the PVs."""
    import random
    m = emu.memory
    _in_band_without_heating(emu)
    st = emu.model(Fun86Model).states[0]
    rng = random.Random(1)
    ahead = []
    for trial in range(120):
        m.set("R4008", 65535)
        emu.scan()
        emu.advance(rng.uniform(0.0, 30.0))  # ends off the grid, wherever the time runs out
        m.set("R4008", 100)
        since = emu.scans_represented
        for _ in range(rng.randint(1, 12)):
            emu.scan()
            counted = emu.scans_represented - since
            if st.prealarm.max() > counted:
                ahead.append((trial, counted, st.prealarm.tolist()))
    assert ahead == []


def test_a_prealarm_count_never_runs_ahead_of_the_scans_of_a_real_time_plc_that_fell_behind(emu):
    """The same in real time, as `hil emulate` runs: the engine scans on its own (time scale 50) and the host
    stalls it (the lock held) for more scans than it catches up one by one, so it jumps — clipped at the wall
    clock's time, off the grid — and the readings of the jump are replayed.  Read at the end of a scan, as port 0
    answers, no count exceeds the scans the counter shows since R4008 went under the PVs (before the fix one point
    ran a scan ahead in about a third of the stalls)."""
    import random
    import threading
    import time
    _in_band_without_heating(emu)
    st = emu.model(Fun86Model).states[0]
    stop = threading.Event()
    runner = threading.Thread(target=emu.run_realtime, args=(stop, 50.0), daemon=True)
    runner.start()
    rng = random.Random(0)
    ahead = []
    try:
        for trial in range(20):
            emu.service(lambda mem: mem.set("R4008", 65535))
            with emu.lock:  # the host stalls: 0.25 s is 1250 scans at time scale 50, past realtime_catch_up
                time.sleep(rng.uniform(0.25, 0.35))
            since = emu.service(lambda mem: (mem.set("R4008", 100), emu.scans_represented)[1])
            for _ in range(rng.randint(3, 12)):
                counted, count = emu.service(
                    lambda mem, since=since: (emu.scans_represented - since, int(st.prealarm.max())))
                if count > counted:
                    ahead.append((trial, counted, count))
    finally:
        stop.set()
        runner.join(timeout=10)
    assert emu.realtime_catch_up < 0.25 * 50 / emu.scan_time  # (the stall is long enough to make it jump)
    assert ahead == []


def test_a_virtual_day_with_every_en_off_is_still_one_jump(emu):
    emu.advance(86400)
    assert emu.scans < 10  # (counted, not timed: wall-clock limits are flaky on shared machines)


# -- plc.pid's closed-loop trace, from any target ----------------------------------------------------------------------
@pytest.mark.parametrize("target", EMULATOR_TARGETS)
def test_a_plot_ready_trace_from_every_target(target):
    bench = Bench(load_profile(EMULATOR_BENCH), target=target)
    try:
        pid = bench.plc.pid
        inst = pid.instance("zone-a")
        bench.begin_test()
        pid.enable(inst)
        pid.set_set_point(3, 600)
        trace = pid.record(3, 60, every=10)
        columns = trace.columns()
        assert list(columns) == ["t", "pv", "sv", "output"]
        assert len(columns["t"]) == 7 and columns["t"] == sorted(columns["t"])
        assert columns["sv"] == [60.0] * 7 and columns["pv"][-1] > columns["pv"][0]
        assert max(columns["output"]) == 100.0
        assert trace.to_csv().splitlines()[0] == "t_s,pv,sv,output_percent"
    finally:
        bench.end_test()
        bench.close()


def test_the_plant_under_a_fixed_pwm_is_solved_in_closed_form_over_whole_periods():
    """A day under one PWM waveform (no scan re-anchors it): the closed form over whole periods equals stepping
    the PWM period by period through its switches on the scan grid, up to rounding (the grid's switch times carry
    float errors of ~1e-11 s at a day, which stepping sums and the closed form does not: ~5e-10 °C apart).  It
    costs a few exponentials whatever the span, where stepping costs two per period."""
    import math

    import numpy as np

    from hil.families.fbs.sim.models.plant_solution import waved_temperature
    started, period, on, st, tau = 0.12, 2.0, 0.6543, 0.01, 250.0

    def closed_form(t: float) -> float:  # anchored at 40 °C at 0.37 s, heater 320 °C on, 20 °C off
        return float(waved_temperature(np.array([0.37]), np.array([40.0]), np.array([t]), np.array([True]), started,
                                       period, on, 320.0, 20.0, tau, st)[0])

    def grid(x: float) -> float:
        return math.ceil(x / st - 1e-6) * st

    def stepped(t: float) -> float:
        temp, at, k = 40.0, 0.37, 0
        while at < t:
            for until, target in ((grid(started + k * period + on), 320.0), (grid(started + (k + 1) * period), 20.0)):
                end = min(max(until, at), t)
                temp = target + (temp - target) * math.exp(-(end - at) / tau)
                at = end
            k += 1
        return temp

    for t in (0.5, 1.0, 2.13, 7.77, 100.0, 3600.0, 86400.0):
        assert math.isclose(closed_form(t), stepped(t), rel_tol=1e-10), t
    assert 20.0 < closed_form(86400.0) < 320.0
