"""``hil emulate`` in real time behaves like a PLC on a wire: it scans on its own and answers each request at the end
of a scan, so two requests in a row always have a whole scan between them (checked from the client's side through
the bench ladder's scan counter, as a bench would), and the RTC set M1952 := 1 … := 0 sent back to back lands."""

from __future__ import annotations

import datetime as dt
import threading
import time

import pytest

from hil.bench.profile import load_profile
from hil.families.fbs.rtc_time import RtcTime
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.transport.factory import open_transport
from tests.conftest import EMULATOR_BENCH
from tests.external import hil_emulate

COUNTER = "R3999"


def bench_like(text: str) -> str:
    """The emulator profile, which declares the bench ladder's scan counter."""
    assert f'scan_counter = "{COUNTER}"' in text
    return text


@pytest.fixture(scope="module")
def emulated(tmp_path_factory):
    profile = tmp_path_factory.mktemp("rt") / "bench.toml"
    profile.write_text(bench_like(EMULATOR_BENCH.read_text()))
    with hil_emulate(profile, 1.0, modbus=True) as where:
        yield where


@pytest.mark.e2e
@pytest.mark.parametrize("url", ["fatek+tcp://{fatek-tcp}", "modbus+tcp://{modbus-tcp}?unit=1"])
def test_every_request_is_answered_after_a_scan_of_its_own(emulated, url):
    link = open_transport(url.format_map(emulated), timeout=2.0)
    try:
        seen = [link.read(COUNTER) for _ in range(30)]
    finally:
        link.close()
    steps = [(b - a) % 65536 for a, b in zip(seen, seen[1:])]
    assert min(steps) >= 1, f"two requests answered with no scan between them: counter {seen}"


@pytest.mark.e2e
@pytest.mark.parametrize("url", ["fatek+tcp://{fatek-tcp}", "modbus+tcp://{modbus-tcp}?unit=1"])
def test_an_rtc_set_sent_back_to_back_lands(emulated, url):
    """M1952 := 1 with the fields, then M1952 := 0 at once, as a client that trusts the port would: the PLC has
    scanned between them, so the clock takes the time (it did not in the old real-time mode)."""
    link = open_transport(url.format_map(emulated), timeout=2.0)
    sent = RtcTime.from_datetime(dt.datetime(2031, 7, 4, 12, 0, 0))
    try:
        link.write_many([("M1952", 1), *zip(("R4128", "R4129", "R4130", "R4131", "R4132", "R4133", "R4134"),
                                            sent.to_registers())])
        link.write("M1952", 0)
        time.sleep(0.05)
        shown = RtcTime.from_registers(link.read_words("R4128", 7)).to_datetime()
    finally:
        link.close()
    assert dt.timedelta(0) <= shown - sent.to_datetime() <= dt.timedelta(seconds=3), shown


def test_the_engine_scans_on_its_own_and_serves_requests_at_scan_boundaries():
    """In process, the same engine: with nobody asking, scans go on at the scan time; a request waits for the
    end of the scan in progress (never more than a scan or two at time scale 1)."""
    emulator = build_emulator(load_profile(EMULATOR_BENCH), dt.datetime(2030, 1, 1))
    stop = threading.Event()
    runner = threading.Thread(target=emulator.run_realtime, args=(stop, 1.0))
    runner.start()
    try:
        deadline = time.monotonic() + 60  # a hang guard
        while emulator.scans < 20:  # nobody asks: it scans on its own
            assert time.monotonic() < deadline, "hang guard: the PLC does not scan on its own"
            time.sleep(0.01)
        before = emulator.scans
        served_at = emulator.service(lambda mem: emulator.scans)
        assert served_at > before  # it waited for the end of a scan (never served mid-scan)
        # (how long a request waits for its scan's end is a benchmark's figure: benchmarks/run.py, wire round trips)
    finally:
        stop.set()
        runner.join(5)
    assert not runner.is_alive()
    assert emulator.service(lambda mem: 1) == 1  # after the stop, requests are serviced in virtual time again
