"""The S7-200 SMART behind the one guard (hil.bench.guard): refusal before any request, its originals journaled
and restored, the clock kept at its offset, and no way round the guard from the bench fixture."""

from __future__ import annotations

import datetime as dt

import pytest

from hil.bench.family import open_bench
from hil.bench.profile import load_profile
from hil.core.errors import WriteRefused
from hil.families.s7smart.protocol import timebuf
from hil.families.s7smart.sim.emulator import build_s7_emulator
from hil.families.s7smart.transport.io import GuardedS7Io, LocalS7Io
from tests.conftest import REPO

S7_BENCH = REPO / "fixtures" / "benches" / "s7-200smart.toml"


@pytest.fixture
def s7():
    emulator = build_s7_emulator(load_profile(S7_BENCH), dt.datetime(2024, 6, 15, 8, 30))
    return emulator, GuardedS7Io(LocalS7Io(emulator), ["VB100-VB101", "VB200-VB203", "Q0.0-Q0.3"])


def test_a_refused_write_sends_nothing(s7):
    emulator, io = s7
    before, requests = emulator.memory.snapshot(), emulator.stats["requests"]
    with pytest.raises(WriteRefused, match="VB204 not in the bench's \\[safety\\] writable"):
        io.write_v(202, b"\x01\x02\x03")  # VB204 is outside
    with pytest.raises(WriteRefused, match="VB204"):
        io.write("VW203", 1)
    with pytest.raises(WriteRefused, match="Q0.4"):
        io.write("Q0.4", 1)
    assert emulator.stats["requests"] == requests
    assert emulator.memory.snapshot() == before


def test_a_v_bit_journals_its_byte_the_first_original_stays_and_restore_verifies(s7):
    emulator, io = s7
    emulator.memory.write_bytes("V", 200, b"\x81\x42")
    io.write("V200.1", 1)  # a bit of a listed byte is writable; the wire rewrites the whole byte: journal VB200
    io.write_v(200, b"\x00\x00")
    io.write("Q0.2", 1)
    assert {str(e): v for e, v in io.journal.items()} == {"VB200": 0x81, "VB201": 0x42, "Q0.2": 0}
    io.restore()
    assert emulator.memory.read_bytes("V", 200, 2) == b"\x81\x42" and emulator.memory.get("Q0.2") == 0
    assert io.journal == {}


@pytest.mark.parametrize("target", ["emulator", "emulator+s7-tcp"])
def test_a_clock_a_test_set_is_put_back_at_its_offset_with_the_programs_results(target):
    if target == "emulator+s7-tcp":
        pytest.importorskip("snap7", reason="python-snap7 (pip install 'hil[s7]') is not installed")
    bench = open_bench(load_profile(S7_BENCH), target=target)
    try:
        rtc, error = bench.plc.rtc, bench.layout.error.byte
        offset = (rtc.read_time() - bench.time.calendar()).total_seconds()
        bench.begin_test("test_sets_the_clock")
        results = bench.raw.read_v(error, 2)  # what the test program left before the test
        assert rtc.set(timebuf.encode(dt.datetime(2099, 12, 31, 23, 59))).accepted
        assert rtc.set(b"\x24\x02\x30\x09\x00\x00\x00\x06").error == timebuf.ERROR_T_DATA  # leaves 0007H
        bench.wait(30)
        bench.end_test()
        assert bench.raw.read_v(error, 2) == results, "the program's error code the test made is put back"
        after = (rtc.read_time() - bench.time.calendar()).total_seconds()
        assert abs(after - offset) <= 1, f"the clock's offset from the bench's time moved by {after - offset} s"
    finally:
        bench.close()


BYPASSES = '''
import pytest
from hil.core.errors import WriteRefused
from hil.plugin.pytest_plugin import BENCH_SESSION

pytestmark = pytest.mark.family("s7-200smart")


@pytest.fixture
def sent(request):  # what reached the CPU, counted by the harness's own emulator
    emulator = request.config.stash[BENCH_SESSION].bench.raw.emulator
    return lambda: emulator.stats["requests"]


@pytest.mark.parametrize("path", ["raw", "io", "journal", "plc.io.inner", "plc.io._write_v", "plc.io._write_bits",
                                  "plc.io.write_back", "plc.io.journal", "plc.io.emulator", "plc.rtc.plc.io.inner"])
def test_no_way_round_the_guard(bench, path):
    obj = bench
    with pytest.raises(AttributeError):
        for part in path.split("."):
            obj = getattr(obj, part)


@pytest.mark.parametrize("write", [lambda io: io.write_v(300, b"\\x01"), lambda io: io.write("VW299", 1),
                                   lambda io: io.write("Q0.0", 1)], ids=["VB300", "VW299", "Q0.0"])
def test_cannot_write_outside_the_allow_list(bench, sent, write):
    before = sent()
    with pytest.raises(WriteRefused):
        write(bench.plc.io)
    assert sent() == before


def test_the_guarded_operations_are_there(bench):
    bench.plc.io.write_v(200, b"\\x5a")
    assert bench.plc.io.read("VB200") == 0x5A and bench.plc.io.has_cpu_clock is False
'''


def test_the_bench_fixture_has_no_way_round_the_s7_guard(pytester):
    bench = pytester.makefile(".toml", bench=S7_BENCH.read_text().replace('target = "emulator+s7-tcp"',
                                                                        'target = "emulator"'))
    pytester.makepyfile(test_bypass=BYPASSES)
    result = pytester.runpytest_inprocess("--bench", str(bench), "-p", "no:cacheprovider", "-p", "no:hypothesispytest")
    result.assert_outcomes(passed=14)
