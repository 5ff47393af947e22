"""The emulator's pty wires at a serial line's real rate (hil.sim.pacing): a character takes its bits' time.

The time a transfer takes is bounded from below only: a paced line cannot carry N characters in less than N
character times (the pacer hands each slice on at the loop time its last character would have arrived, on the
ideal clock), and a busy host can only make it slower.  How close to the line's rate it comes is a benchmark's
figure (benchmarks/bench_host_time.py).  The floor is computed from the configured rate, never a number written
down here."""

from __future__ import annotations

import asyncio
import os
import select
import time

import pytest

from hil.core.errors import InvalidValue
from hil.families.fbs.protocol.fatek import ReadRegisters, encode_request
from hil.families.fbs.transport.factory import emulator_line, open_transport
from hil.io.url import parse_target
from hil.sim.pacing import LineRate, PacedSender
from hil.sim.ptypair import PtyPair
from hil.sim.runtime import LoopThread
from tests.conftest import EMULATOR_BENCH, REPO


@pytest.mark.parametrize("text, bits", [("9600 7E1", 10), ("9600 8E1", 11), ("115200 8N1", 10), ("19200,8O2", 12)])
def test_a_character_takes_start_data_parity_and_stop_bits(text, bits):
    rate = LineRate.parse(text)
    assert rate.bits == bits
    assert rate.char_time == pytest.approx(bits / rate.baudrate)


@pytest.mark.parametrize("text", ["9600", "fast 7E1", "9600 9E1", "9600 7X1", "10 8N1"])
def test_a_bad_line_setting_is_refused_naming_it(text):
    with pytest.raises(InvalidValue, match="line|baud|frame"):
        LineRate.parse(text)


def test_the_url_sets_the_pace_with_the_protocols_usual_frame():
    assert emulator_line(parse_target("emulator+fatek-serial?baudrate=9600")) == LineRate(9600, 7, "E", 1)
    assert emulator_line(parse_target("emulator+modbus-rtu?baudrate=19200")) == LineRate(19200, 8, "E", 1)
    profile_line = LineRate(115200, 7, "E", 1)
    assert emulator_line(parse_target("emulator+fatek-serial"), profile_line) == profile_line  # the profile's
    assert emulator_line(parse_target("emulator+fatek-serial?baudrate=9600"), profile_line).baudrate == 9600
    assert emulator_line(parse_target("emulator+fatek-tcp"), profile_line) is None  # TCP has no line rate
    with pytest.raises(InvalidValue, match="baudrate"):
        emulator_line(parse_target("emulator+fatek-serial?parity=E"))


#: how long a transfer may go without a byte before the test calls it hung (a hang guard, not a measure)
HANG_GUARD = 60.0
#: asyncio may run a timer up to its clock's resolution early, and the float clock rounds: far below a character
EARLY = 1e-6


def pty_transfer(rate: LineRate | None, size: int, direction: str) -> tuple[int, float]:
    """``size`` bytes written at one end of a paced pty bridge (unpaced: ``rate`` None; benchmarks/bench_host_time.py
    times the same transfer), read at the other: (bytes carried, seconds from
    just before the write to the last byte's arrival) — every byte crossed the pacer within that span."""
    runtime = LoopThread.shared()

    async def start() -> PtyPair:
        return PtyPair(asyncio.get_running_loop(), line=rate)

    pair = runtime.run(start())
    src_path, dst_path = (pair.path_b, pair.path_a) if direction == "b_to_a" else (pair.path_a, pair.path_b)
    src, dst = os.open(src_path, os.O_RDWR | os.O_NOCTTY), os.open(dst_path, os.O_RDWR | os.O_NOCTTY)
    try:
        started, got = time.monotonic(), 0
        os.write(src, bytes(range(256)) * (size // 256))
        while got < size:
            ready, _, _ = select.select([dst], [], [], HANG_GUARD)
            assert ready, f"hang guard: {got} of {size} bytes came, then none for {HANG_GUARD:.0f} s"
            got += len(os.read(dst, 4096))
        return got, time.monotonic() - started
    finally:
        os.close(src)
        os.close(dst)

        async def stop() -> None:
            pair.close()
        runtime.run(stop())


@pytest.mark.parametrize("direction", ["b_to_a", "a_to_b"])
def test_a_paced_pty_carries_a_large_transfer_at_the_line_rate(direction):
    """The Modbus RTU wire's bridge, both ways: 5 KB at 57600 8E1 takes at least its bytes × 11 bit times (≈ 1 s)."""
    rate = LineRate(57600, 8, "E", 1)
    carried, elapsed = pty_transfer(rate, 5120, direction)
    floor = carried * rate.bits / rate.baudrate
    assert carried == 5120  # every byte, in order of arrival (none dropped)
    # the pace is a floor: no faster than the bits allow — a guaranteed lower bound (a busy host is only slower)
    assert elapsed >= floor - EARLY, f"{carried} bytes in {elapsed:.3f} s, faster than the line's {floor:.3f} s"


def test_fatek_frames_on_a_paced_pty_take_their_bytes_times_the_bit_time():
    """Known frames over emulator+fatek-serial at 9600 7E1 (port 0's factory setting): every request and reply
    byte is counted as it goes by, and the exchange takes at least those bytes × 10 / 9600 s (scans are virtual
    here): each request and each reply crosses the pacer whole before the next one is sent."""
    url = "emulator+fatek-serial?baudrate=9600&bytesize=7&parity=E"
    rate = emulator_line(parse_target(url))
    with open_transport(url) as plc:
        plc.read_words("R0", 1)  # the detailed status and the port's first use out of the way
        carried = []
        plc.observers.append(lambda direction, frame: carried.append(len(frame)))
        started = time.monotonic()
        for _ in range(4):
            assert plc.read_words("R0", 64) == [0] * 64
        elapsed = time.monotonic() - started
    floor = sum(carried) * rate.bits / rate.baudrate
    frames = len(encode_request(1, ReadRegisters("R0", 64))) + 9 + 64 * 4  # the request; STX…ETX around 64 words
    assert sum(carried) == 4 * frames, "one request and its reply a read, nothing else (no fence on a direct line)"
    # a guaranteed lower bound, as above (no upper one: a busy host is only slower)
    assert elapsed >= floor - EARLY, (f"{sum(carried)} bytes in {elapsed:.3f} s, faster than the line's "
                                      f"{floor:.3f} s at {rate}")


def test_a_flood_on_a_paced_line_is_bounded_and_dropped_beyond_the_buffer():
    runtime = LoopThread.shared()
    seen: list[bytes] = []

    async def flood() -> PacedSender:
        sender = PacedSender(asyncio.get_running_loop(), LineRate(9600, 7, "E", 1), seen.append)
        sender.send(b"x" * (200 * 1024))
        return sender

    sender = runtime.run(flood())
    assert sender.dropped == 200 * 1024 - 64 * 1024

    async def stop() -> None:
        sender.close()
    runtime.run(stop())


#: the smoke and RTC suites (the drift measurement aside: on a bench it is a slow test of hours)
PACED_SUITES = [str(REPO / "suites" / f) for f in ("test_smoke.py", "test_rtc.py", "test_rtc_midnight.py",
                                                    "test_rtc_validity.py", "test_rtc_adjust.py")]


# (the FATEK case in the matrix: the gate runs the smoke and RTC suites over hil emulate's paced pty in two lanes,
# tests/test_lanes.py — the gate's time)
@pytest.mark.parametrize("target, suites, least", [
    pytest.param("emulator+fatek-serial?baudrate=115200&bytesize=7&parity=E", PACED_SUITES, 24,
                 marks=pytest.mark.matrix),
    ("emulator+modbus-rtu?baudrate=115200&parity=E", PACED_SUITES[:1], 5)], ids=["fatek", "modbus-rtu"])
def test_the_smoke_and_rtc_suites_pass_over_a_paced_line(pytester, target, suites, least):
    """At 115200 bit/s (9600 costs a minute of line time here: benchmarks/run.py measures that one against
    ``hil emulate``); the client's deadlines, partial frames and the procedures' waits meet a line's timing.
    Modbus RTU runs the smoke suite (its RTC checks are the same procedures over the same bridge)."""
    result = pytester.runpytest_inprocess(*suites, "--bench", str(EMULATOR_BENCH), "--target", target, "-rs",
                                          "-p", "no:cacheprovider", "-p", "no:hypothesispytest")
    outcomes = result.parseoutcomes()
    assert outcomes.get("failed", 0) == 0 and outcomes.get("error", 0) == 0, result.stdout.str()[-3000:]
    assert outcomes["passed"] >= least


def test_a_profile_sets_the_pace_and_a_bad_one_is_refused_naming_the_key():
    from hil.bench.profile import profile_from_dict
    from hil.core.errors import ProfileError
    base = {"bench": {"name": "b", "target": "emulator+fatek-serial"}}
    assert profile_from_dict({**base, "emulator": {"line": "9600 7E1"}}).emulator.line == LineRate(9600, 7, "E", 1)
    assert profile_from_dict(base).emulator.line is None  # unpaced unless asked
    with pytest.raises(ProfileError, match=r"\[emulator\] line"):
        profile_from_dict({**base, "emulator": {"line": "9600 baud"}})


def test_every_fatek_device_operation_on_port_0_costs_at_most_1_3_times_its_fewest_bytes():
    """benchmarks/run.py's per-operation table, on a paced 9600 7E1 line as port 0 is wired (a direct line: fenced
    only after a timeout or retry, docs/safety.md — whatever fences it sends are counted): each procedure's request
    and reply bytes against the fewest its steps need in the cheapest frames."""
    from benchmarks.run import _device_operations
    rows = _device_operations("emulator+fatek-serial?baudrate=9600&bytesize=7&parity=E")
    assert {r["operation"] for r in rows} >= {"rtc.read()", "rtc.set()", "rtc.adjust_30s()", "temperature.readings()"}
    over = [f"{r['operation']}: {r['bytes']} bytes for {r['min_bytes']} ({r['ratio']:.2f}×)" for r in rows
            if r["bytes"] > 1.3 * r["min_bytes"]]
    assert not over, over
