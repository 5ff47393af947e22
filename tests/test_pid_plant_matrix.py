"""The closed-loop PID suites on plants a bench may have: a point that cools fast when its heater circuit opens, a
slow and sluggish oven, a long dead time (the emulator's [plant] models each).  The suites must pass on every one
(a correct PLC), and still catch a FUN86 that ignores R4006 on the fast-cooling plant."""

from __future__ import annotations

import re

import pytest

from tests.conftest import EMULATOR_BENCH, REPO
from tests.test_pid_suites import HeaterLoopIgnoresR4006, Variant

SUITES = [str(REPO / "suites" / "test_pid.py"), str(REPO / "suites" / "test_pid_control.py")]
INNER = ("-p", "no:hypothesispytest", "-p", "no:cacheprovider", "-rfs")
#: name → [plant] (time constant 60–3600 s, gain 100–1000 °C, dead time up to 10 s, cooling up to 2 °C/s)
PLANTS = {
    # starts at 200 °C: with the heater open it cools at (200 − 25) / 90 ≈ 1.9 °C/s
    "fast-cooling": {"ambient": 25.0, "gain": 300.0, "tau": 90.0, "dead_time": 0.0, "initial": 200.0, "noise": 0.05},
    "slow-sluggish": {"ambient": 25.0, "gain": 1000.0, "tau": 3600.0, "dead_time": 5.0, "noise": 0.03},
    "dead-time": {"ambient": 25.0, "gain": 100.0, "tau": 60.0, "dead_time": 10.0, "noise": 0.03},
}


def _bench(tmp_path, plant: dict) -> str:
    text = EMULATOR_BENCH.read_text()
    table = "[plant]\n" + "".join(f"{k} = {v}\n" for k, v in plant.items())
    text = re.sub(r"(?ms)^\[plant\]\n.*?(?=^\[|\Z)", table, text)
    path = tmp_path / "bench.toml"
    path.write_text(text)
    return str(path)


#: what runs on each plant: the fast-cooling point is not at rest when a test starts (it cools whatever the
#: output), which is the heater-open case the heater-loop tests meet; the others run both suites whole (25 tests
#: since the ERR pairs and each band edge's two sides became one test each; the same margin of 8 kept)
RUNS = {"fast-cooling": (SUITES[1:], ("-k", "heater_loop"), 3), "slow-sluggish": (SUITES, (), 17),
        "dead-time": (SUITES, (), 17)}


@pytest.mark.timeout(180)
@pytest.mark.parametrize("plant", [pytest.param(name, marks=() if name == "fast-cooling" else pytest.mark.matrix)
                                   for name in PLANTS])  # the gate: the plant the defect below needs
def test_the_pid_suites_pass_on_every_plant(pytester, tmp_path, plant):
    files, extra, at_least = RUNS[plant]
    result = pytester.runpytest_inprocess(*files, *INNER, *extra, "--bench", _bench(tmp_path, PLANTS[plant]))
    outcomes = result.parseoutcomes()
    assert outcomes.get("failed", 0) == 0 and outcomes.get("error", 0) == 0, result.stdout.str()[-4000:]
    assert outcomes.get("passed", 0) >= at_least, result.stdout.str()[-2000:]


@pytest.mark.timeout(180)
def test_a_fun86_ignoring_r4006_is_caught_on_the_fast_cooling_plant(pytester, tmp_path):
    result = pytester.inline_run(SUITES[1], *INNER, "--bench", _bench(tmp_path, PLANTS["fast-cooling"]),
                                 "-k", "threshold", plugins=[Variant(HeaterLoopIgnoresR4006)])
    failed = [r.nodeid for r in result.getreports("pytest_runtest_logreport") if r.when == "call" and r.failed]
    assert any("R4006-80-warns" in f for f in failed), failed
