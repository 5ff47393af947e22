"""Waiting for an event at the cadence of what is awaited (hil.families.fbs.device.waiting), on virtual time."""

from __future__ import annotations

from hil.bench.profile import load_profile
from hil.core.timebase import EmulatorTimebase
from hil.families.fbs.bench import Bench
from hil.families.fbs.device.waiting import POLLS_PER_PERIOD, poll_until
from hil.families.fbs.sim.plc import Emulator
from tests.conftest import EMULATOR_BENCH


def test_an_event_is_looked_at_a_fraction_of_its_period_and_given_up_at_the_worst_case():
    clock = EmulatorTimebase(Emulator())
    looks: list[float] = []

    def event() -> bool:
        looks.append(clock.now())
        return clock.now() >= 3.0

    assert poll_until(clock, event, period=4.0, within=8.0)
    gaps = {round(b - a, 6) for a, b in zip(looks, looks[1:])}
    assert gaps == {round(4.0 / POLLS_PER_PERIOD, 6)}  # neither back to back nor a whole period apart
    assert 3.0 <= looks[-1] < 3.0 + 4.0 / POLLS_PER_PERIOD + 1e-9  # seen within the fraction after it came
    looks.clear()
    assert not poll_until(clock, lambda: event() and False, period=4.0, within=8.0)
    assert looks[-1] - looks[0] == 8.0  # the last look at the limit itself


def test_fun86_is_awaited_at_the_pid_interval_of_r4005():
    bench = Bench(load_profile(EMULATOR_BENCH))
    try:
        pid = bench.plc.pid
        assert pid.timing() == (4, 2)  # power-on R4005 = 0102H: every 4 s, PWM period 2 s
        # bench time on the in-process emulator is its virtual clock: exact, whatever the host's load (no host time
        # is compared with anything here)
        assert bench.time.virtual
        started = bench.time.now()
        assert not pid.wait_until(lambda: False, steps=1.0)
        elapsed = bench.time.now() - started
        assert 4 + 2 <= elapsed < 4 + 2 + 0.1  # one interval and a PWM period (each look: a scan more)
    finally:
        bench.close()
