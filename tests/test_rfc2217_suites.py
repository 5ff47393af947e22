"""The smoke and RTC suites pass over ``fatek+rfc2217://`` and ``modbus+rfc2217://``: ``hil emulate`` in real time
(time scale 10, as tests/test_bench_mode.py) serves its pty, an RFC 2217 server exports it — ser2net where
installed, as a labgrid exporter would, else pyserial's port manager — and the suites reach the PLC only through
that server, as a bench whose port 0 hangs off an exporter.  One wire after the other: two accelerated runs side
by side on a loaded 2-core host miss the suites' windows."""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import sys

import pytest

from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import bench_over_the_wire, emulate_process
from tests.rfc2217_servers import rfc2217_server
from tests.test_bench_mode import ALLOWED_SKIPS, bench_like, outcome_counts

SUITES = [str(REPO / "suites" / f) for f in
          ("test_smoke.py", "test_rtc.py", "test_rtc_midnight.py", "test_rtc_validity.py", "test_rtc_adjust.py",
           "test_rtc_drift.py")]
TIME_SCALE = 5.0  # the RTC suites keep a real bench's slack on a busy host (and the pty, ser2net and RFC 2217 hops)
#: protocol → (the endpoint kind hil emulate prints, its option, URL scheme, query)
WIRES = {
    "fatek": ("fatek-serial", "--fatek-serial", "fatek+rfc2217", "station=1"),  # 9600 7E1: port 0's factory setting
    # pymodbus paces an RTU client by the baud rate it is told (3.5 characters of silence): a pty has none
    "modbus": ("modbus-rtu", "--modbus-rtu", "modbus+rfc2217", "unit=1&baudrate=115200&parity=E"),
}


@pytest.mark.e2e
@pytest.mark.timeout(300)
# the matrix only (the gate's time): tests/test_rfc2217.py holds the RFC 2217 wire itself in the gate
@pytest.mark.matrix
@pytest.mark.parametrize("protocol", list(WIRES))
def test_smoke_and_rtc_suites_pass_over_rfc2217(tmp_path, protocol):
    kind, option, scheme, query = WIRES[protocol]
    emulated = tmp_path / "emulated.toml"
    emulated.write_text(bench_like(EMULATOR_BENCH.read_text()))
    with contextlib.ExitStack() as stack:
        where = stack.enter_context(emulate_process(emulated, TIME_SCALE,
                                                    {kind: option, "rig-modbus-tcp": "--rig-modbus-tcp"}))
        # ser2net's chardelay (≈ 3 ms a reply at 9600) would be 30 ms of PLC time a request at time scale 10: the
        # RTC suites' ±1 s windows are for a bench in real time
        server = stack.enter_context(rfc2217_server(where[kind], chardelay=False))
        bench = tmp_path / f"{protocol}.toml"
        bench.write_text(bench_over_the_wire(emulated.read_text(), where, TIME_SCALE,
                                             url=f"{scheme}://{server.rfc2217}?{query}"))
        out = subprocess.run([sys.executable, "-m", "pytest", *SUITES, "--bench", str(bench), "-rsfE", "-p",
                              "no:cacheprovider", "-p", "no:hypothesispytest"],
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp_path, timeout=240,
                             env={**os.environ, "PYTHONUNBUFFERED": "1"}).stdout
    counts = outcome_counts(out)
    print(f"{protocol}+rfc2217 via {server.kind}: {counts}")
    assert counts.get("failed", 0) == 0 and counts.get("error", 0) + counts.get("errors", 0) == 0, out[-6000:]
    assert counts.get("passed", 0) >= 25, out[-3000:]  # the RTC suites fold cases that share a wait
    assert f"hil target: {protocol}+rfc2217://" in out, out[:3000]  # the session header names the target
    for line in out.splitlines():
        if line.startswith("SKIPPED"):
            assert any(re.search(allowed, line) for allowed in ALLOWED_SKIPS + [r"pass --hil-run-slow"]), line
