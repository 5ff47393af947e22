"""The pytest plugin end to end: suites over every emulator target, restore after failure, skips by marker."""

from __future__ import annotations

import pytest

from hil.families.fbs.sim import Emulator
from tests.conftest import EMULATOR_BENCH, EMULATOR_TARGETS, REPO


class KeepEmulator:
    """A plugin object for the inner pytest run: builds the emulator and keeps it for the outer test to inspect."""

    def __init__(self) -> None:
        self.emulator: Emulator | None = None

    def pytest_hil_make_emulator(self, profile, epoch):
        from hil.families.fbs.sim.build import build_emulator
        self.emulator = build_emulator(profile, epoch)
        return self.emulator


@pytest.mark.parametrize("target", EMULATOR_TARGETS)
def test_smoke_suite_passes_on_every_emulator_target(pytester, target):
    result = pytester.runpytest_inprocess(str(REPO / "suites" / "test_smoke.py"), "--bench", str(EMULATOR_BENCH),
                                          "--target", target, "-p", "no:cacheprovider")
    result.assert_outcomes(passed=5)


def test_failing_test_leaves_the_emulator_as_it_found_it(pytester):
    pytester.makepyfile(test_breaks="""
        def test_writes_then_fails(bench):
            bench.plc.io.write_words("R1000", [11, 22, 33])
            bench.plc.io.write_bits("M1000", [1, 1])
            bench.plc.io.write_many({"R1050": 7})
            assert bench.plc.io.read_words("R1000", 3) == [0, 0, 0], "deliberate failure after writing"
    """)
    keep = KeepEmulator()
    # Values already there before the test: the guard must put exactly these back.
    original = {"R1000": 5, "R1001": 6, "M1001": 1}

    class Seed(KeepEmulator):
        def pytest_hil_make_emulator(self, profile, epoch):
            emulator = KeepEmulator.pytest_hil_make_emulator(keep, profile, epoch)
            for name, value in original.items():
                emulator.memory.set(name, value)
            return emulator

    result = pytester.inline_run("--bench", str(EMULATOR_BENCH), plugins=[Seed()])
    result.assertoutcome(failed=1)
    mem = keep.emulator.memory
    assert mem.read("R1000", 3) == [5, 6, 0]
    assert mem.read("M1000", 2) == [0, 1]
    assert mem.get("R1050") == 0


def test_markers_skip_with_reasons_on_a_real_bench_target(pytester):
    pytester.makepyfile(test_marks="""
        import pytest

        @pytest.mark.needs("virtual_time", reason="jumps virtual time")
        def test_needs_emulator(bench): pass

        @pytest.mark.slow
        def test_slow(bench): pass

        @pytest.mark.destructive
        def test_destructive(bench): pass
    """)
    from hil.families.fbs.sim.plc import Emulator
    from hil.families.fbs.transport.factory import serve
    server = serve(Emulator(), "fatek-tcp")  # a PLC on a wire, as a bench's (a bench that cannot be opened stops
    try:                                     # the run before collection: tests/test_first_hour.py)
        bench_file = pytester.makefile(".toml", bench=f"""
            [bench]
            name = "on a wire"
            target = "fatek+tcp://{server.address}"
            timeout = 1
        """)
        result = pytester.runpytest_inprocess("--bench", str(bench_file), "-rs")
    finally:
        server.stop()
    result.assert_outcomes(skipped=3)
    result.stdout.fnmatch_lines(["*needs virtual_time: jumps virtual time*", "*--hil-run-slow*",
                                 "*--hil-allow-destructive*"])
