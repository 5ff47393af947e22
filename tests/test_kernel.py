"""The compiled span kernel is the Python models, faster: the same virtual hours run both ways must leave every
register, every model's state and the clock identical — in configurations that reach each branch the kernel
mirrors (heater-loop timer, pre-alarm counting, disabled and broken points, cooling, ramps, °F, fast rate, two
instances, requests in between) — and where it does not apply, it must step aside."""

from __future__ import annotations

import datetime as dt

import pytest

from hil.families.fbs.sim import kernel
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.models.fun86 import Fun86Model
from hil.families.fbs.sim.models.plant import ThermalPlant
from hil.families.fbs.sim.models.temperature import Ramp, TemperatureModel
from hil.bench.profile import load_profile, profile_from_dict
from tests.conftest import EMULATOR_BENCH

pytestmark = pytest.mark.skipif(not kernel.available(), reason="the compiled kernel is not built (no C compiler at "
                                "install, or HIL_KERNEL=0): the emulator runs its Python models alone")

EPOCH = dt.datetime(2024, 2, 28, 23, 0, 0)
FULL_MODULES = [{"type": "6TC", "sensor": "K"}] * 4 + [{"type": "2TC", "sensor": "K"}] * 4
PID_32 = {"en": "M0", "sn": 0, "zn": 32, "yn": "Y0", "sv": "R1000", "os": "R1040", "pr": "R1080", "ir": "R1120",
          "dr": "R1160", "or": "R1200", "wr": "R1240"}


def profile(modules=None, plant=None, pid=None, **temperature):  # noqa: ANN001, ANN201
    base = load_profile(EMULATOR_BENCH)
    area = dict(base.areas["temperature"], **temperature)
    if modules is not None:
        area["modules"] = modules
    return profile_from_dict({"bench": {"name": "kernel"}, "rtc": {"chip": 3, "crystal_ppm": 12.5},
                              "temperature": area, "pid": pid if pid is not None else base.areas["pid"],
                              "plant": plant if plant is not None else {}})


def state(emu) -> dict:  # noqa: ANN001
    """Everything a scan can change: memory, the clock, and each model's state."""
    tm, fun86, plant = emu.model(TemperatureModel), emu.model(Fun86Model), emu.model(ThermalPlant)
    return {
        "clock": (emu.now, emu.scans), "memory": emu.memory.snapshot(),
        "temperature": (list(tm._next), list(tm._mux), {p: list(s) for p, s in tm._samples.items()}, tm._breaks,
                        sorted(tm._measured), tm.state),
        "fun86": ([(st.next_pid, st.running, st.waiting, st.sn, st.zn,
                    [(ps.integral, ps.pv_prev, ps.prealarm, ps.loop_since) for ps in st.points.values()])
                   for st in fun86.states], dict(fun86.waveforms), fun86.waveforms_version),
        "plant": [(h.t0, h.temp0, h.wave) for h in plant.points.values()],
    }


def outputs(emu) -> list[tuple[int, ...]]:  # noqa: ANN001
    """Per running FUN86 instance: WR+0…3, ALM, Yn… as a bit mask, the sum of OR — the kernel's trace record."""
    mem, fun86 = emu.memory, emu.model(Fun86Model)
    rows = []
    for inst, st in zip(fun86.config.instances, fun86.states):
        if st.running:
            wr, ys = mem.words[inst.wr.kind], mem.bits[inst.yn.kind]
            rows.append((*wr[inst.wr.index:inst.wr.index + 4], mem.bits[inst.alm.kind][inst.alm.index],
                         sum(ys[inst.yn.index + b] << b for b in range(st.zn)),
                         sum(mem.words[inst.or_.kind][inst.or_.index:inst.or_.index + st.zn])))
    return rows


def traced(emu) -> list:  # noqa: ANN001
    """Record :func:`outputs` after every scan, the Python models' and the kernel's alike (in order)."""
    trace: list = []
    scan = emu.scan

    def scan_and_record() -> None:
        scan()
        trace.append((emu.now, outputs(emu)))
    emu.scan = scan_and_record
    emu.kernel_trace = trace
    return trace


def both_ways(build, drive) -> dict:  # noqa: ANN001
    """Run ``drive(emu)`` on two fresh emulators, without and with the kernel: every scan's outputs must match
    (a difference that lasts one scan counts), and so must the final states; returns the Python models' state."""
    python, compiled = build(), build()
    python.use_kernel = False
    python_trace, compiled_trace = traced(python), traced(compiled)
    drive(python)
    drive(compiled)
    assert python.stats["kernel_spans"] == 0
    assert compiled.stats["kernel_spans"] > 0, "the kernel never ran: this test would prove nothing"
    assert len(compiled_trace) == len(python_trace)
    for (now, rows), (k_now, k_rows) in zip(python_trace, compiled_trace):
        assert (k_now, k_rows) == (now, rows), f"the scans at {now} s differ"
    final, compiled_final = state(python), state(compiled)
    for part in final:
        assert compiled_final[part] == final[part], part
    return final


def start(emu, en: str = "M0", hc: str = "M1", heating: bool = True, sv: dict | None = None,  # noqa: ANN001
          enable: int = 0xFFFFFFFF, **registers: int) -> None:
    mem = emu.memory
    mem.set(en, 1)
    mem.set(hc, 1 if heating else 0)
    mem.set("R4012", enable & 0xFFFF)
    mem.set("R4013", enable >> 16)
    for name, value in (sv or {}).items():
        mem.set(name, value)
    for name, value in registers.items():
        mem.set(name, value)


def full_plc(**plant):  # noqa: ANN003, ANN201
    return lambda: build_emulator(profile(FULL_MODULES, plant=plant, pid=PID_32), EPOCH)


def test_the_full_plc_for_an_hour():
    def drive(emu) -> None:  # noqa: ANN001
        start(emu, sv={f"R{1000 + p}": 1500 for p in range(32)})
        emu.advance(3600)
    python = both_ways(full_plc(), drive)
    assert python["memory"]["words"]["R"][1240] != 0  # some points reached their band: the loops ran


def test_the_heater_loop_timer_opens_the_same_way():
    """Gain 50 °C: 150.0 °C is out of reach, the output stays at 100 % and the heater-loop warning comes on."""
    def drive(emu) -> None:  # noqa: ANN001
        start(emu, sv={f"R{1000 + p}": 1500 for p in range(32)}, R4006=80, R4007=90)
        emu.advance(900)
    python = both_ways(full_plc(gain=50.0), drive)
    assert python["memory"]["words"]["R"][1242] == 0xFFFF  # WR+2: every point 0–15 warns


def test_pre_alarm_counting_scan_by_scan_is_the_same():
    """R4008 below the set point: readings cross it, so every measurement gets its scan and the count runs."""
    def drive(emu) -> None:  # noqa: ANN001
        start(emu, sv={f"R{1000 + p}": 1500 for p in range(32)}, R4008=1400)
        emu.advance(1800)
    python = both_ways(full_plc(), drive)
    assert python["memory"]["words"]["R"][1242] != 0  # pre-alarm warnings


def test_a_pre_alarm_limit_exactly_at_the_readings_bound():
    """R4008 = the highest reading the plant can ever give: still "could reach", so measurements get their scans."""
    def drive(emu) -> None:  # noqa: ANN001
        start(emu, sv={f"R{1000 + p}": 1500 for p in range(32)})
        emu.advance(30)
        bound = emu.model(TemperatureModel).readings_upper(emu.memory, range(32))
        emu.service(lambda mem: mem.set("R4008", int(bound)))
        emu.advance(120)
    both_ways(full_plc(), drive)


def test_two_instances_with_disabled_broken_and_missing_points_cooling_and_a_ramp():
    """The default bench: zone-a heats points 0–9 with a broken sensor on 3 and 6 disabled; zone-b (Md 1) cools
    12–31 with point 20 not installed; point 10 is unheated and follows a ramp."""
    def build():  # noqa: ANN202
        emu = build_emulator(profile(), EPOCH)
        emu.model(TemperatureModel).set_source(10, Ramp(20.0, 0.05, high=90.0))
        emu.model(TemperatureModel).open(3)
        return emu

    def drive(emu) -> None:  # noqa: ANN001
        start(emu, sv={f"R{100 + b}": 800 + 10 * b for b in range(10)}, enable=0xFFFFFFFF & ~(1 << 6))
        start(emu, en="M2", hc="M3", heating=False, sv={f"R{400 + b}": 300 for b in range(20)},
              enable=0xFFFFFFFF & ~(1 << 6), R4011=0xFFFF & ~(1 << 4))
        emu.advance(1200)
    both_ways(build, drive)


@pytest.mark.parametrize("unit, rate, averaging", [("F", "normal", 1), ("C", "fast", 1), ("F", "fast", 1),
                                                    ("C", "normal", 4), ("F", "fast", 8), ("C", "normal", 2)])
def test_fahrenheit_the_fast_rate_and_averaging(unit, rate, averaging):
    def drive(emu) -> None:  # noqa: ANN001
        start(emu, sv={f"R{1000 + p}": 2200 if unit == "F" else 1200 for p in range(32)}, R4008=1150)
        emu.advance(900)
    build = lambda: build_emulator(profile(FULL_MODULES, pid=PID_32, unit=unit, rate=rate,  # noqa: E731
                                           averaging=averaging), EPOCH)
    both_ways(build, drive)


def test_requests_between_spans():
    """A test polling and changing set points, R4005 and the enable mask: each request, then a span."""
    def drive(emu) -> None:  # noqa: ANN001
        start(emu, sv={f"R{1000 + p}": 1200 for p in range(32)})
        for n in range(12):
            emu.advance(47.3)
            readings = emu.service(lambda mem: mem.read("R3020", 32))
            assert len(readings) == 32
            emu.service(lambda mem, n=n: mem.write("R1000", [1200 + 25 * n] * 8))
            if n == 5:
                emu.service(lambda mem: mem.set("R4012", 0xF0F0))
            if n == 7:
                emu.service(lambda mem: (mem.set("M0", 0)))  # EN off → on: R4005 latches again
                emu.service(lambda mem: (mem.set("R4005", 0x0102), mem.set("M0", 1)))
    both_ways(full_plc(noise=0.2, tau=120.0), drive)


# -- where it steps aside --------------------------------------------------------------------------------------------
def kernel_spans(build, action=None) -> int:  # noqa: ANN001
    emu = build()
    start(emu, sv={f"R{1000 + p}": 1500 for p in range(32)})
    if action:
        action(emu)
    emu.advance(600)
    return emu.stats["kernel_spans"]


def test_it_applies_to_the_full_plc():
    assert kernel_spans(full_plc()) > 0


def test_it_steps_aside_for_a_plant_fault_dead_time_and_broken_variants():
    assert kernel_spans(full_plc(), lambda emu: emu.model(ThermalPlant).set_fault("heater_open", 2, True)) == 0
    assert kernel_spans(full_plc(dead_time=2.0)) == 0

    class SlowCount(Fun86Model):  # a broken PLC's seam: the kernel is not that PLC
        def prealarm_count(self, count: int, pv: int, limit: int) -> int:
            return count

    def swap(emu) -> None:  # noqa: ANN001
        old = emu.model(Fun86Model)
        new = SlowCount(old.config, old.temperature)
        new.__dict__.update(old.__dict__)
        emu.models[emu.models.index(old)] = new
        emu.model(ThermalPlant)._fun86 = new
    assert kernel_spans(full_plc(), swap) == 0


def test_switched_off_by_the_environment(monkeypatch):
    monkeypatch.setenv("HIL_KERNEL", "0")
    assert not kernel.available()
    assert kernel_spans(full_plc()) == 0


def test_the_field_layouts_are_the_extensions():
    """kernel.py addresses records by the names the C module exports: every name it packs must exist there."""
    from hil.families.fbs.sim import _kernel
    assert set(_kernel.FIELDS) == {"engine", "modules", "tpoints", "plant", "instances", "pids"}
    assert {"now", "target", "scans", "version"} <= set(_kernel.FIELDS["engine"])
    with pytest.raises(ValueError, match="float64"):
        _kernel.run(bytearray(8), *([bytearray(8)] * 6))
