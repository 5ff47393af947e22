"""The S7-200 SMART over its own protocol (s7+tcp://, python-snap7): the emulator served over S7, reached by hil's
io and by python-snap7's own client; the suites against ``hil emulate --s7-tcp`` in another process."""

from __future__ import annotations

import datetime as dt
import re
import subprocess
import sys

import pytest

from hil.bench.family import open_bench
from hil.bench.profile import load_profile
from hil.core.errors import HilError, TargetError
from hil.families.s7smart.protocol import timebuf
from hil.families.s7smart.sim.emulator import build_s7_emulator
from hil.families.s7smart.sim.serve_s7 import start_s7_server
from hil.families.s7smart.transport import s7wire
from hil.io.url import parse_target
from tests.conftest import REPO
from tests.external import emulate_process

snap7 = pytest.importorskip("snap7", reason="python-snap7 (pip install 'hil[s7]') is not installed")
S7_BENCH = REPO / "fixtures" / "benches" / "s7-200smart.toml"
EPOCH = dt.datetime(2024, 6, 15, 8, 30)


@pytest.fixture
def served():
    emulator = build_s7_emulator(load_profile(S7_BENCH), EPOCH)
    server = start_s7_server(emulator)
    host, _, port = server.address.rpartition(":")
    yield emulator, host, int(port)
    server.stop()


def independent_client(host: str, port: int):
    client = snap7.client.Client()
    client.connect(host, 0, 1, port)
    return client


def test_the_target_url():
    target = parse_target("s7+tcp://192.0.2.7?rack=0&slot=1")
    assert (target.host, target.port, target.params, target.protocol) == ("192.0.2.7", 102, {"rack": 0, "slot": 1},
                                                                            "s7")
    assert parse_target("emulator+s7-tcp").in_process
    with pytest.raises(TargetError, match="unknown parameter 'unit'"):
        parse_target("s7+tcp://host?unit=1")


def test_an_independent_client_reads_and_writes_the_emulators_v_memory(served):
    emulator, host, port = served
    client = independent_client(host, port)
    try:
        client.db_write(1, 300, bytearray(b"\x12\x34\x56"))
        assert emulator.memory.read_bytes("V", 300, 3) == b"\x12\x34\x56"  # the emulator's memory, not the server's
        emulator.memory.write_bytes("V", 310, b"\xAB\xCD")
        assert bytes(client.db_read(1, 310, 2)) == b"\xAB\xCD"
        emulator.memory.set("Q0.3", 1)
        assert client.read_area(snap7.type.Area.PA, 0, 0, 1)[0] & 0x08
    finally:
        client.disconnect()


def test_an_independent_client_sees_the_clock_buffer_the_suites_see(served, tmp_path):
    emulator, host, port = served
    url = f"s7+tcp://{host}:{port}"
    mine = tmp_path / "s7.toml"  # a bench's profile for that CPU (a PLC runs only with a profile naming it)
    mine.write_text(S7_BENCH.read_text().replace('target = "emulator+s7-tcp"', f'target = "{url}"', 1))
    profile = load_profile(mine)
    bench = open_bench(profile, target=url)  # hil's path: the bench over the S7 wire
    try:
        result = bench.plc.rtc.read()
        assert result.accepted
        client = independent_client(host, port)
        try:
            layout = profile.sections["s7rtc"]
            assert bytes(client.db_read(1, layout.read_buffer.byte, 8)) == result.buffer
            clock = client.get_plc_datetime()  # the protocol's clock function reads the same clock
            assert abs((clock - timebuf.decode(result.buffer)).total_seconds()) <= 2
        finally:
            client.disconnect()
    finally:
        bench.close()


def test_unmapped_areas_are_refused_with_the_s7_error(served):
    _emulator, host, port = served
    io = s7wire.SnapS7Io(host, port, timeout=1.0)
    try:
        assert "not reached over this wire" in io.unreachable_reason("SMB0")
        with pytest.raises(HilError, match="refused"):
            io._call("read DB2", lambda: io.client.db_read(2, 0, 4))
        with pytest.raises(HilError, match="outside V memory"):
            io.read_v(20478, 4)
    finally:
        io.close()


def test_a_missing_extra_is_one_line_saying_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "snap7", None)
    with pytest.raises(HilError, match=r"pip install 'hil\[s7\]'"):
        s7wire.snap7_module()


def test_nobody_listening_is_a_clear_error():
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # closed again: nothing listens there
    with pytest.raises(HilError, match="cannot connect to s7\\+tcp://127.0.0.1"):
        s7wire.SnapS7Io("127.0.0.1", port, timeout=0.5)


@pytest.mark.matrix  # the gate runs the S7 suites over emulator+s7-tcp (tests/test_s7_suites_catch_broken_plcs.py)
def test_the_s7_suites_pass_against_hil_emulate_in_another_process(tmp_path):
    """``hil emulate --s7-tcp`` as a separate real-time process (time scale 20), the suites over s7+tcp://."""
    with emulate_process(S7_BENCH, 20, {"s7-tcp": "--s7-tcp"}) as endpoints:
        profile = tmp_path / "s7-bench.toml"
        text = re.sub(r'(?m)^target = .*$', f'target = "s7+tcp://{endpoints["s7-tcp"]}"', S7_BENCH.read_text())
        # the emulator follows the spec's readings: declared as a bench's owner would ([our choice] tests run)
        text = re.sub(r"(?m)^time_scale = .*$", "", text).replace(
            "[bench]", '[bench]\ntime_scale = 20\noffers = ["spec_choices"]', 1)
        profile.write_text(text)
        run = subprocess.run([sys.executable, "-m", "pytest", str(REPO / "suites" / "s7smart"), "--bench",
                              str(profile), "-q", "-rs", "-p", "no:cacheprovider"], cwd=tmp_path,
                             capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    summary = next(line for line in reversed(run.stdout.splitlines()) if re.search(r" in [\d.]+s", line))  # pytest's
    assert re.search(r"\d+ passed", summary) and "failed" not in summary, summary
    skips = [line for line in run.stdout.splitlines() if line.startswith("SKIPPED")]
    # a bench cannot cut the power on demand, nor show a CPU straight from power-on (hil emulate offers neither)
    assert all("needs power_cycle" in line or "needs power_on_state" in line for line in skips), skips
