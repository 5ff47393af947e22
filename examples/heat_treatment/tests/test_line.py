"""Tests a machine builder writes for a heat-treatment line: its own FUN86 boxes, its own alarm words, its clock.

Run them (from examples/heat_treatment):
    hil run --bench bench.toml -- tests          (JUnit + HTML report in reports/)
    pytest --bench bench.toml tests              (plain pytest; the hil plugin is loaded by its entry point)

They reach the PLC only through the shipped fixtures (``bench``, ``pid``, ``temperature``, ``rtc``, ``io``,
``measure``, ``report``) and wait in bench time, so they run unchanged in virtual time on the in-process emulator,
against ``hil emulate`` on a wire, and on the line's real PLC.  What the line's ladder must do is in the
expectations: nothing here asks the emulator what the right answer is.
"""

from __future__ import annotations

import datetime as dt

import pytest

from hil.api import Bench, Measure, Pid, PlcIO, Report, Rtc, Temperature

OVEN_POINT = 4  # the oven's first thermocouple (its FUN86 box: Sn 4, Zn 2)
#: the oven's commissioned gains (Kc, Ki, Td): switching EN on loads FUN86's defaults, so a test sets its own
OVEN_GAINS = (110, 17, 50)
BAND = 50  # Os, 0.1 °C: the oven is "in band" within SV ± 5.0 °C
STEP = 300  # a set-point step of 30.0 °C
SETTLE_S = 120  # the line's specification: in band within 2 minutes of a 30 °C step …
HOLD_S = 30  # … and staying there
SHIFT_REGISTER = "R1500"  # scratch: where this test puts the shift-change time the ladder compares R4135 with
SHIFT_CHANGE = dt.time(6, 0)


@pytest.fixture
def oven(bench: Bench, pid: Pid, temperature: Temperature) -> int:
    """The oven box switched on (heating) with its commissioned gains; its first point's number.  Everything
    written here is put back when the test ends."""
    box = pid.instance("oven")
    pid.enable(box, True, heating=True)
    pid.set_gains(OVEN_POINT, *OVEN_GAINS)
    pid.set_deviation(OVEN_POINT, BAND)
    bench.settle()
    return OVEN_POINT


@pytest.mark.bench_time(SETTLE_S + HOLD_S + 10, reason="the oven's settling time and hold")
@pytest.mark.measures("oven_settle_time", unit="s", low=0, high=SETTLE_S)
def test_a_set_point_step_settles_in_band(oven: int, pid: Pid, measure: Measure, report: Report) -> None:
    sv = pid.pv(oven) + STEP
    pid.set_set_point(oven, sv)
    trace = pid.record(oven, SETTLE_S + HOLD_S, every=2.0)
    columns = trace.columns()
    report.attach_series("oven_step", {"t": columns["t"], "PV": columns["pv"], "SV": columns["sv"]},
                         title=f"oven point {oven}: a {STEP / 10} °C step", xlabel="s", ylabel="°C")
    inside = trace.settled_at(BAND)
    assert inside is not None, f"PV never stayed within SV {sv / 10} ± {BAND / 10} °C: last {trace.samples[-1]}"
    measure("oven_settle_time", inside)  # unit and limits: the declaration above
    assert pid.alarm_words(pid.instance("oven")).normal(oven), "PV in band: WR+0's bit for the point is set"


def test_the_over_temperature_pre_alarm_trips(bench: Bench, oven: int, pid: Pid, io: PlcIO) -> None:
    """Manual 20.7: a warning bit (WR+2) and ALM once PV ≥ R4008 for 10 consecutive scans; none while PV is below
    it.  The limit is set around the oven's present temperature, so the oven need not heat up for it."""
    box = pid.instance("oven")
    pid.set_set_point(oven, pid.pv(oven))  # hold where it is
    io.write("R4008", max(100, pid.pv(oven) + 100))  # 10 °C above PV (R4008's range starts at 10.0 °)
    assert not pid.wait_until(lambda: pid.alarm_words(box).warning(oven), steps=1), \
        "pre-alarm with PV 10 °C below R4008"
    if pid.pv(oven) - 100 < 100:
        pytest.skip(f"the oven is at {pid.pv(oven) / 10} °C: R4008 cannot be set 10 °C below it")
    io.write("R4008", pid.pv(oven) - 100)  # 10 °C below PV: the oven is "over temperature"
    assert pid.wait_until(lambda: pid.alarm_words(box).warning(oven)), "no pre-alarm with PV 10 °C above R4008"
    assert pid.alm(box), "the pre-alarm sets the box's ALM"


def test_a_shift_change_time_in_r4135_matches_the_clock(bench: Bench, rtc: Rtc, io: PlcIO) -> None:
    """The ladder changes shift when R4135 (hour << 8 | minute) equals the shift-change time: R4135 must turn to
    06:00 when the clock does, and say the same hour and minute as R4128–R4134 of the same scan."""
    io.write(SHIFT_REGISTER, SHIFT_CHANGE.hour << 8 | SHIFT_CHANGE.minute)
    today = bench.time.calendar().date()  # the bench's calendar (virtual on the emulator), not datetime.now()
    before = dt.datetime.combine(today, SHIFT_CHANGE) - dt.timedelta(seconds=3)
    assert rtc.set(before), f"the PLC refused {before} (M1955)"
    shift = io.read(SHIFT_REGISTER)
    for _ in range(10):  # 3 s to go: look every second for up to 10
        *fields, hour_minute = io.read_words("R4128", 8)  # R4128–R4135 in one request: one scan
        if hour_minute == shift:
            break
        bench.wait(1.0)
    else:
        pytest.fail(f"R4135 never reached {shift:04X}H in 10 s after the clock was set to {before:%H:%M:%S}")
    second, minute, hour = fields[:3]
    assert (hour, minute) == (SHIFT_CHANGE.hour, SHIFT_CHANGE.minute), \
        f"R4135 = {hour_minute:04X}H while R4128–R4130 say {hour:02}:{minute:02}:{second:02}"
