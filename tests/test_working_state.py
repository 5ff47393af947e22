"""A suite's working state (``pytest.mark.working_state``, :meth:`hil.bench.guard.Guard.hold`): journaled as every
write is, put back once when the suite's last test ends — not after each test — and never at the cost of what the
PLC is left as: a crash, the session's end or another module's first test puts it back all the same."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from hil.families.fbs.address import parse
from hil.families.fbs.transport.guard import GuardedTransport
from hil.families.fbs.transport.local import LocalTransport
from tests.conftest import EMULATOR_BENCH, REPO
from tests.test_plugin import KeepEmulator


def _guarded(emulator):
    return GuardedTransport(LocalTransport(emulator), writable=["R100-R109"])


def test_held_words_stay_between_tests_journaled_and_go_back_verified_when_the_hold_ends(emulator):
    emulator.memory.write("R100", [7, 8, 9])
    guard = _guarded(emulator)
    guard.hold([parse("R100"), parse("R101")])
    guard.begin("first")
    guard.write_words("R100", [1, 2, 3])
    guard.end()
    # R100/R101 held: still the test's, their originals kept; R102 went back at once
    assert emulator.memory.read("R100", 3) == [1, 2, 9]
    assert {str(e): v for e, v in guard.journal.items()} == {"R100": 7, "R101": 8}
    guard.begin("second")
    requests = emulator.stats["requests"]
    guard.write_words("R100", [4])
    assert emulator.stats["requests"] == requests + 1, "a held word's original is known: only the write goes out"
    guard.end()
    assert {str(e): v for e, v in guard.journal.items()} == {"R100": 7, "R101": 8}
    restored = guard.release()
    assert sorted(str(e) for e, _ in restored) == ["R100", "R101"]
    assert emulator.memory.read("R100", 3) == [7, 8, 9]
    assert guard.journal == {} and guard.held == frozenset()


def test_the_sessions_end_puts_held_words_back_whatever_hold_is_left(emulator):
    emulator.memory.write("R105", [5])
    guard = _guarded(emulator)
    guard.hold([parse("R105")])
    guard.begin("interrupted")
    guard.write_words("R105", [99])
    guard.end()
    guard.finish()
    assert emulator.memory.read("R105", 1) == [5] and guard.journal == {}


def test_a_held_clock_goes_back_when_the_hold_ends_not_after_each_test(emulator):
    from hil.bench.base import BenchBase
    from hil.bench.profile import load_profile
    from hil.families.fbs.bench import Bench
    from hil.families.fbs.rtc_time import RtcTime
    bench = Bench(load_profile(EMULATOR_BENCH), target="emulator")
    assert isinstance(bench, BenchBase)
    assert bench.time.virtual  # the emulator's clock: the seconds below are virtual ones, exact whatever the host
    before, since = bench.plc.rtc.read().to_datetime(), bench.time.now()
    bench.hold(["clock"])
    bench.begin_test("sets the clock")
    bench.plc.rtc.set(RtcTime.from_datetime(before.replace(year=2031)))
    bench.end_test()
    assert bench.plc.rtc.read().year == 31, "held: the clock stays as the test left it"
    bench.time.wait(600.0)  # the next test of the module, say: ten minutes of (virtual) bench time
    bench.release()
    # back where it would be had it never been set: the time it showed, plus the bench time since (to the second
    # the chip keeps, and the second a set lands on)
    drift = (bench.plc.rtc.read().to_datetime() - before).total_seconds() - (bench.time.now() - since)
    assert abs(drift) <= 2, drift
    bench.close()


def test_pid_working_state_is_the_inputs_of_the_boxes_that_are_off():
    from hil.bench.profile import load_profile
    from hil.families.fbs.bench import Bench
    bench = Bench(load_profile(EMULATOR_BENCH), target="emulator")
    bench.raw.emulator.memory.set("M2", 1)  # zone-b (EN M2) runs: the ladder's, its words go back every test
    held, clock = bench.working_state(["pid", "scratch"])
    names = {str(e) for e in held}
    assert not clock
    assert {"R100", "R109", "R110", "R120", "R130", "R149"} <= names  # zone-a: SV, Os, PR, IR, DR (Zn 10)
    assert not names & {"R200", "R300"}, "OR and WR are FUN86's outputs: never held"
    zone_b = next(i for i in bench.plc.pid.config.instances if i.name == "zone-b")
    assert str(zone_b.sv) not in names
    assert {"R1000", "R1099", "M1000", "D3031"} <= names  # the [bench] scratch
    bench.close()


def test_a_marked_module_holds_its_words_until_its_last_test_and_the_next_module_finds_them_back(pytester):
    pytester.makepyfile(test_a_held="""
        import pytest
        pytestmark = pytest.mark.working_state("scratch")

        def test_one(bench):
            bench.plc.io.write_words("R1000", [11])
            bench.plc.io.write_words("R1050", [1])

        def test_two(bench):
            assert bench.plc.io.read_words("R1000", 1) == [11]  # held: the first test's value
            bench.plc.io.write_words("R1000", [12])
    """, test_b_plain="""
        def test_finds_the_original(bench):
            assert bench.plc.io.read_words("R1000", 1) == [5]
            bench.plc.io.write_words("R1000", [13])

        def test_then_plain_per_test_restore(bench):
            assert bench.plc.io.read_words("R1000", 1) == [5]
    """)
    keep = KeepEmulator()

    class Seed:
        def pytest_hil_make_emulator(self, profile, epoch):
            emulator = keep.pytest_hil_make_emulator(profile, epoch)
            emulator.memory.set("R1000", 5)
            return emulator

    result = pytester.inline_run("--bench", str(EMULATOR_BENCH), "-p", "no:cacheprovider", plugins=[Seed()])
    result.assertoutcome(passed=4)
    assert keep.emulator.memory.read("R1000", 1) == [5]
    assert keep.emulator.memory.read("R1050", 1) == [0]


def test_a_run_stopped_inside_a_held_module_leaves_the_plc_as_found(pytester):
    pytester.makepyfile(test_stops="""
        import pytest
        pytestmark = pytest.mark.working_state("scratch")

        def test_one(bench):
            bench.plc.io.write_words("R1000", [11])

        def test_two(bench):
            bench.plc.io.write_words("R1001", [12])
            assert False, "deliberate: -x stops the run inside the hold"

        def test_three(bench):
            pass
    """)
    keep = KeepEmulator()
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), "-x", "-p", "no:cacheprovider",
                                          plugins=[keep])
    result.assert_outcomes(passed=1, failed=1)
    assert keep.emulator.memory.read("R1000", 2) == [0, 0]
    out = result.stdout.str()
    assert "a failed restore" not in out, "the hold's words went back at the session's end: no restore had failed"
    assert "the PLC is as it was found" in out


def test_what_a_hold_keeps_is_not_reported_as_left_by_a_failed_restore():
    """At the session's end a hold still in force (the run stopped inside its module) is the session end's to put
    back: the safety report's "a failed restore left these" list names only what a restore failed to put back."""
    from hil.bench.profile import load_profile
    from hil.families.fbs.bench import Bench
    from hil.plugin.safety import _unrestored
    bench = Bench(load_profile(EMULATOR_BENCH), target="emulator")
    bench.hold(["scratch"])
    bench.begin_test("holds R1000")
    bench.plc.io.write_words("R1000", [7])
    bench.end_test()
    assert _unrestored(bench, exact=False) == []
    assert _unrestored(bench) == ["R1000 (original 0)"]
    bench.finish()
    assert _unrestored(bench) == [] and bench.raw.emulator.memory.read("R1000", 1) == [0]
    bench.close()


HELD_MODULE = """
import os, signal, time
import pytest
pytestmark = pytest.mark.working_state("scratch")

def test_one(bench):
    bench.plc.io.write_words("R1000", [11, 12])

def test_two_dies_inside_the_hold(bench):
    assert bench.plc.io.read_words("R1000", 2) == [11, 12]  # held: still the first test's
    os.kill(os.getpid(), signal.SIG{sig})
    time.sleep(30)

def test_three(bench):
    pass
"""


@pytest.mark.e2e
@pytest.mark.parametrize("sig", ["KILL", "TERM"])
def test_a_run_killed_inside_a_hold_leaves_hil_emulate_as_found(tmp_path, sig):
    """Against ``hil emulate`` as a separate real-time process over FATEK/TCP, with the durable journal: a run
    SIGKILLed while a module holds its working state leaves the held words changed on the PLC, journaled — the
    next session's recovery puts them back; a SIGTERMed run puts them back itself before it exits."""
    from hil.families.fbs.transport.factory import open_transport
    from hil.io.url import parse_target
    from tests.external import bench_over_the_wire, hil_emulate
    profile = tmp_path / "emulated.toml"
    profile.write_text(EMULATOR_BENCH.read_text())
    (tmp_path / "held").mkdir()
    (tmp_path / "held" / "test_held.py").write_text(HELD_MODULE.replace("{sig}", sig))
    (tmp_path / "next").mkdir()
    (tmp_path / "next" / "test_next.py").write_text("def test_next_session(bench):\n    pass\n")
    with hil_emulate(profile, 1.0) as where:
        target = f"fatek+tcp://{where['fatek-tcp']}"
        bench = tmp_path / "bench.toml"
        bench.write_text(bench_over_the_wire(EMULATOR_BENCH.read_text(), where, 1.0))
        inner = ["-p", "no:cacheprovider", "-p", "no:hypothesispytest", "--bench", str(bench), "-q"]

        def r1000() -> list[int]:
            with open_transport(parse_target(target), timeout=30.0) as t:  # a hang guard (hil emulate is real time)
                return t.read_words("R1000", 2)

        assert r1000() == [0, 0]
        run = subprocess.run([sys.executable, "-m", "pytest", str(tmp_path / "held"), *inner], cwd=REPO,
                             capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        assert run.returncode != 0, "a killed run is never PASSED"
        if sig == "KILL":
            assert r1000() == [11, 12], "SIGKILL: nothing could put the held words back yet"
            nxt = subprocess.run([sys.executable, "-m", "pytest", str(tmp_path / "next"), *inner], cwd=REPO,
                                 capture_output=True, text=True, timeout=120)
            assert nxt.returncode == 0 and "hil bench recovery: a previous run" in nxt.stdout, nxt.stdout[-2000:]
        assert r1000() == [0, 0], run.stdout[-2000:]
