"""Issue 25, items 5–7, against ``hil emulate`` as a separate real-time process: the clock's origin taken at a
second transition and kept on the monotonic base within a session (no loss per run, a host clock step moves
nothing), a dead run's origin checked against the host's clocks, and forced bits (FATEK 42/43) put back exactly.

Offsets are measured as the guard takes them, by timing the PLC's second transitions (a whole-second reading is
up to a second off), here against the host's real wall clock.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import re
import socket
import time
from collections.abc import Iterator

import pytest

from hil.bench.guard import ORIGIN_MAX_AGE, OriginRefused, origin_from_journal
from hil.bench.profile import load_profile
from hil.core.journal import Journal, JournalError
from hil.core.timebase import HostClocks, HostTimebase
from hil.families.fbs.bench import Bench
from hil.families.fbs.device.plc import FbsPlc
from tests.conftest import EMULATOR_BENCH
from tests.external import bench_over_the_wire, hil_emulate

#: what ten runs may move the clock's offset from host time by, all told (issue 25)
TEN_RUNS = 0.050
#: what one session may move it by: about a round trip (the guard restores on its monotonic base, exact to the
#: reply of the set) — a precision only a quiet host shows, so the matrix (--matrix) holds it; the gate holds what
#: the PLC itself shows, a whole second, which an hour's step or a lost second would break
ONE_SESSION = TEN_RUNS / 10 + 0.010
WHOLE_SECOND = 1.0


def one_session_bound(config) -> float:
    return ONE_SESSION if config.getoption("--matrix") else WHOLE_SECOND
REAL_TIME = time.time  # the host's wall clock, whatever a test does to time.time

pytestmark = pytest.mark.e2e  # hil emulate in real time


@pytest.fixture(scope="module")
def emulated(tmp_path_factory):
    # 2 ms scans (a small ladder's): the PLC answers at a scan's end, so a restore is exact to about a round trip
    # and a timing to a scan — with the bundled 10 ms the ten runs' random walk would not fit 50 ms reliably
    path = tmp_path_factory.mktemp("emulated") / "emulated.toml"
    path.write_text(EMULATOR_BENCH.read_text().replace("scan_time_ms = 10", "scan_time_ms = 2"))
    with hil_emulate(path, 1) as where:
        yield where


@pytest.fixture
def profile(tmp_path, emulated):
    path = tmp_path / "bench.toml"
    path.write_text(bench_over_the_wire(EMULATOR_BENCH.read_text(), emulated, 1))
    return load_profile(path)


def _offset(profile) -> float:
    """PLC − host wall clock (s) at one of the PLC's second transitions, over the profile's wire, unguarded."""
    bench = Bench(profile)
    try:
        plc, at, _ = FbsPlc(bench.raw, bench.time).rtc.time_transition()
        wall = REAL_TIME() - (bench.time.now() - at)  # time_scale 1: bench seconds are host seconds
        return plc.replace(tzinfo=dt.UTC).timestamp() - wall
    finally:
        bench.close()


def _a_run_that_sets_the_clock(profile, *, dies: bool = False) -> Bench:
    """One session as `hil run` has it: a test sets the RTC, its end restores, the session's end restores exactly
    (``dies``: the run is killed after the set — nothing restored, the journal left behind)."""
    bench = Bench(profile)
    bench.begin_test("suites/test_rtc.py::test_sets_the_clock")
    assert bench.plc.rtc.set(dt.datetime(2099, 12, 31, 23, 59)).accepted
    if not dies:
        bench.end_test()
        bench.finish()
    bench.close()
    return bench


# -- item 5: no second lost per run ----------------------------------------------------------------------------
@pytest.mark.matrix  # ten sessions' precision in ms: the host's load is in it
# ten sessions, each a set and an exact restore (often two sets: Guard._put_exactly): ≈ 60 s alone
@pytest.mark.timeout(240)
def test_ten_runs_that_set_the_clock_leave_its_offset_within_50_ms(profile):
    # Ten sessions in one process: each a new bench (guard, journal, origin) on a new connection, as ten
    # `hil run`s are — what a run adds to the offset is its origin's timing and its exact restore, both here.
    before = _offset(profile)
    for _ in range(10):
        bench = _a_run_that_sets_the_clock(profile)
        assert not bench.journal.path.exists()
    moved = _offset(profile) - before
    assert abs(moved) <= TEN_RUNS, f"ten runs moved the clock's offset from host time by {moved * 1000:+.1f} ms"


def test_a_crash_and_its_recovery_leave_the_offset_within_a_round_trip(profile, pytestconfig):
    before = _offset(profile)
    dead = _a_run_that_sets_the_clock(profile, dies=True)
    assert Journal(dead.journal.key).clock() is not None
    bench = Bench(profile)
    try:
        report = bench.recover()
        assert report.ok, report.summary()
    finally:
        bench.close()
    moved = _offset(profile) - before
    bound = one_session_bound(pytestconfig)
    assert abs(moved) <= bound, f"a crash and recovery moved the offset by {moved * 1000:+.1f} ms (> {bound} s)"


# -- item 6: a host clock step moves nothing ---------------------------------------------------------------------
@pytest.mark.matrix  # the gate holds the recovery's refusal of a stepped origin (below, and test_recovery_left_changed)
def test_a_host_clock_step_during_a_run_does_not_move_the_plc_clock(profile, monkeypatch, pytestconfig):
    before = _offset(profile)
    bench = Bench(profile)
    try:
        bench.begin_test("suites/test_rtc.py::test_sets_the_clock")
        bench.plc.rtc.set(dt.datetime(2099, 12, 31, 23, 59))
        with monkeypatch.context() as step:
            step.setattr(time, "time", lambda: REAL_TIME() - 3600)  # NTP steps the host clock back an hour
            bench.end_test()
            bench.finish()
    finally:
        bench.close()
    moved = _offset(profile) - before
    bound = one_session_bound(pytestconfig)
    assert abs(moved) <= bound, f"the PLC clock moved {moved:+.3f} s with the host clock's step (> {bound} s)"


@pytest.mark.parametrize("step", [3600.0, -3600.0])
def test_recovery_carries_an_origin_across_a_host_clock_step_on_the_boot_clock(profile, monkeypatch, pytestconfig,
                                                                               step):
    # NTP steps the host's wall clock an hour either way between a killed run and its recovery: the boot clock (the
    # reference a live session keeps the origin on) spans the time since, so the PLC's clock goes back to the offset
    # it had before the run, and the step is reported, not carried (issue 40, item 10; a 5 ms step on a busy VM
    # had made the refusal this replaced fail the gate)
    before = _offset(profile)
    _a_run_that_sets_the_clock(profile, dies=True)
    bench = Bench(profile)
    try:
        with monkeypatch.context() as stepped:
            stepped.setattr(time, "time", lambda: REAL_TIME() + step)
            report = bench.recover()
    finally:
        bench.close()
    assert report.ok, report.summary()
    said = " ".join(report.verified)
    assert re.search(re.escape(f"wall clock was stepped by {step:+.0f}.") + r"\d{3} s", said), said
    moved = _offset(profile) - before
    bound = one_session_bound(pytestconfig)
    assert abs(moved) <= bound, f"recovered across a {step:+.0f} s host clock step, the offset moved {moved:+.3f} s"


def _entry(wall: float, **more) -> dict:
    return {"plc": "2026-01-01T00:00:00", "host": wall, "scale": 1.0, **more}


def test_an_origin_too_old_in_the_future_or_from_another_boot_is_refused_a_stepped_one_carried():
    now = HostClocks(wall=1_000_000.0, since_boot=500.0, boot="b")
    with pytest.raises(OriginRefused, match="h old"):
        origin_from_journal(_entry(now.wall - ORIGIN_MAX_AGE - 1, boot="a", since_boot=1.0), HostTimebase(), now)
    with pytest.raises(OriginRefused, match="in the future"):
        origin_from_journal(_entry(now.wall + 5), HostTimebase(), now)
    timebase = HostTimebase()
    # same boot: 100 s on the boot clock, 3700 on the wall — carried by the boot clock, the wall's step measured
    stepped = origin_from_journal(_entry(now.wall - 3700, boot="b", since_boot=400.0), timebase, now)
    assert abs(stepped.original(timebase) - dt.datetime(2026, 1, 1, 0, 1, 40)) < dt.timedelta(seconds=0.01)
    assert stepped.host_step == pytest.approx(3600.0)
    origin = origin_from_journal(_entry(now.wall - 100.25, boot="b", since_boot=399.75), timebase, now)
    assert abs(origin.original(timebase) - dt.datetime(2026, 1, 1, 0, 1, 40, 250000)) < dt.timedelta(seconds=0.01)
    assert origin.host_step == 0.0  # (wall and boot clocks agree)
    # another boot: nothing to compare with but the age — only a person can accept it (issue 40, item 10)
    with pytest.raises(OriginRefused, match="another boot.*--accept-host-clock"):
        origin_from_journal(_entry(now.wall - 3700, boot="a", since_boot=400.0), timebase, now)
    assert origin_from_journal(_entry(now.wall - 3700, boot="a", since_boot=400.0), timebase, now,
                               accept_host_clock=True)


# -- item 7: forced bits stay forced --------------------------------------------------------------------------
FORCED = ["M1001", "M1002"]  # an operator disabled (forced) these; M1003 is enabled


@contextlib.contextmanager
def _forced_by_an_operator(profile) -> Iterator[Bench]:
    """A bench on a PLC where an operator forced M1001 and M1002 (by hand, not through the guard); un-forced and
    closed afterwards."""
    bench = Bench(profile)
    try:
        for name in ("M1001", "M1002", "M1003"):
            bench.raw.bit_action(name, 2)
        for name in FORCED:
            bench.raw.bit_action(name, 1)
        yield bench
    finally:
        for name in FORCED:
            bench.raw.bit_action(name, 2)
        bench.close()


def _tests_act(bench) -> None:
    bench.begin_test("suites/test_x.py::test_forces")
    io = bench.plc.io
    io.bit_action("M1001", 1)  # disables it (again)
    io.bit_action("M1002", 2)  # enables it
    io.bit_action("M1003", 1)  # disables an enabled one
    assert bench.raw.read_disabled("M1001", 3) == [1, 0, 1]


def test_forced_bits_stay_forced_after_a_clean_run(profile):
    with _forced_by_an_operator(profile) as bench:
        _tests_act(bench)
        assert set(Journal(bench.journal.key).enable_states()) == {"M1001", "M1002", "M1003"}, "journaled first"
        bench.end_test()
        assert bench.raw.read_disabled("M1001", 3) == [1, 1, 0]
        assert not bench.journal.path.exists()


def test_forced_bits_stay_forced_after_a_crash_and_recovery(profile):
    with _forced_by_an_operator(profile) as dead:
        _tests_act(dead)  # then killed: nothing restored
        bench = Bench(profile)
        try:
            report = bench.recover()
            assert report.ok, report.summary()
            assert "M1002 disabled (" in report.summary()  # its original state, named
            assert bench.raw.read_disabled("M1001", 3) == [1, 1, 0]
            assert not bench.journal.path.exists()
        finally:
            bench.close()


def test_an_enable_state_that_cannot_be_journaled_is_not_kept_in_memory_either(tmp_path):
    journal = Journal("tcp://127.0.0.1:500", tmp_path / "gone")  # its directory does not exist: no save succeeds
    with pytest.raises(JournalError):
        journal.add_enable_states({"M1001": True}, {"M1001": False})
    assert journal.enable_states() == {} and not journal.pending  # so the next try saves it again, or fails again
    with pytest.raises(JournalError):
        journal.add_enable_states({"M1001": True}, {"M1001": False})


def test_a_bit_action_that_cannot_be_journaled_is_not_sent(tmp_path):
    bench = Bench(load_profile(EMULATOR_BENCH), target="emulator+fatek-tcp")  # in process, over a real wire
    try:
        bench.io.durable = Journal("tcp://127.0.0.1:500", tmp_path / "gone")  # a journal no save reaches
        for _ in range(2):  # and the second try as well: nothing was kept in memory as journaled
            with pytest.raises(JournalError):
                bench.plc.io.bit_action("M1001", 1)
            assert bench.raw.read_disabled("M1001") == [0]
    finally:
        bench.close()


def _frame(body: str) -> bytes:
    """STX, ``body``, the checksum of STX through the last data character (2 uppercase hex), ETX (spec)."""
    text = "\x02" + body
    return (text + f"{sum(text.encode()) & 0xFF:02X}" + "\x03").encode()


def test_command_43_is_answered_byte_for_byte_as_the_spec_gives_it(profile, emulated):
    with _forced_by_an_operator(profile):  # M1001, M1002 disabled, M1003 enabled
        host, port = emulated["fatek-tcp"].rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=5) as wire:
            wire.sendall(_frame("014303M1001"))  # station 01, command 43, N = 03, start bit M1001
            reply = b""
            while not reply.endswith(b"\x03"):
                reply += wire.recv(64)
        assert reply == _frame("01430110"), reply  # error 0, then one character per bit, 1 = disabled
