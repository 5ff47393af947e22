"""Every way a test's writes get restored — or are reported as not restored — when the wire misbehaves."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest

from hil.core.errors import OutcomeUnknown, RestoreError
from hil.families.fbs.transport.factory import open_transport
from hil.families.fbs.transport.guard import GuardedTransport
from hil.sim.wire_faults import WireFaults
from tests.conftest import EMULATOR_BENCH

WIRES = ["emulator+fatek-tcp", "emulator+fatek-serial", "emulator+modbus-tcp", "emulator+modbus-rtu"]


def _guarded(wire: str, faults: WireFaults) -> GuardedTransport:
    return GuardedTransport(open_transport(wire, timeout=0.3, wire_faults=faults), ["R1000-R1009", "M1000"])


@pytest.mark.parametrize("wire", ["emulator+fatek-tcp", "emulator+modbus-tcp"])
def test_restore_reconnects_after_the_connection_drops(wire):
    faults = WireFaults()
    with _guarded(wire, faults) as io:
        io.write("R1000", 5)
        faults.push("close")  # the server hangs up instead of acknowledging the restore write
        restored = io.restore()
        assert [(str(a), v) for a, v in restored] == [("R1000", 0)]
        assert io.reopened == 1 and io.emulator.memory.get("R1000") == 0


@pytest.mark.parametrize("wire", WIRES)
def test_a_write_whose_reply_is_lost_is_still_restored(wire):
    faults = WireFaults()
    with _guarded(wire, faults) as io:
        # The journal's read of the original passes (fenced on the wires without transaction ids — a FATEK
        # loop-back, an RTU probe read: one more reply); the write's reply is lost.
        faults.push(*[None] * io.requests_per_read, "drop")
        with pytest.raises(OutcomeUnknown, match="outcome unknown"):
            io.write("R1001", 9)
        assert io.emulator.memory.get("R1001") == 9  # it did land
        io.restore()
        assert io.emulator.memory.get("R1001") == 0


@pytest.mark.parametrize("wire", WIRES)
def test_restore_that_cannot_reach_the_plc_lists_what_it_left(wire):
    with _guarded(wire, WireFaults()) as io:
        io.write("R1002", 11)
        io.write("M1000", 1)
        io.inner.server.stop()  # the PLC goes away; reconnecting fails too
        with pytest.raises(RestoreError) as info:
            io.restore()
        listed = {(a, v) for a, v, _ in info.value.failures}
        assert listed == {("R1002", 0), ("M1000", 0)}
        assert "R1002 (original 0)" in str(info.value) and "M1000 (original 0)" in str(info.value)


def _profile(pytester, extra: str = "") -> str:
    text = EMULATOR_BENCH.read_text().replace('target = "emulator"', 'target = "emulator+fatek-tcp"')
    return str(pytester.makefile(".toml", bench=text + extra))


def test_failed_restore_goes_into_the_junit_report(pytester):
    pytester.makepyfile(test_dies="""
        import pytest
        from hil.plugin.pytest_plugin import BENCH_SESSION

        @pytest.fixture
        def real(request):  # the harness's own bench object: its tests break the wire from inside a test
            return request.config.stash[BENCH_SESSION].bench

        def test_writes_then_loses_the_plc(bench, real):
            bench.plc.io.write("R1000", 42)
            real.raw.server.stop()
    """)
    result = pytester.runpytest_inprocess("--bench", _profile(pytester), "--junitxml=report.xml",
                                          "-o", "junit_family=xunit1")
    result.assert_outcomes(passed=1, errors=1)
    result.stdout.fnmatch_lines(["*could not restore 1 address(es): R1000 (original 0)*"])
    props = {p.get("name"): p.get("value") for p in ET.parse(pytester.path / "report.xml").iter("property")}
    assert "R1000 (original 0)" in props["hil_restore_failed"]


def test_a_test_killed_by_pytest_timeout_is_still_restored(pytester):
    pytester.makepyfile(test_hangs="""
        import pytest
        from hil.plugin.pytest_plugin import BENCH_SESSION

        @pytest.fixture
        def real(request):  # the harness's own bench object: its tests break the wire from inside a test
            return request.config.stash[BENCH_SESSION].bench


        @pytest.mark.timeout(1, method="signal")
        def test_hangs_mid_exchange(bench, real):
            bench.plc.io.write("R1000", 7)
            real.raw.server.faults.push("delay")  # the next reply is held 1.5 s; the client waits up to 2 s
            bench.plc.io.read("R1001")

        def test_next_finds_it_restored(bench, real):
            assert bench.plc.io.read_words("R1000", 2) == [0, 0]
            assert real.raw.emulator.memory.get("R1000") == 0
    """)
    bench = _profile(pytester, "\n[wire_faults]\nseed = 1\ndelay_seconds = 1.5\n")
    result = pytester.runpytest_inprocess("--bench", bench, "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines(["*Timeout*"])
