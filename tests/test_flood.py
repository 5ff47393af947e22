"""A flood of junk on one connection does not starve the others (issue 15): while junk pours into ``hil emulate`` on
one connection, another client's requests are all answered, and answered right; the server drops the junk with a
constant amount of work per byte — STX (02H) bytes on FATEK/TCP (hil.families.fbs.protocol.fatek.FrameAssembler),
bogus MBAP headers with huge lengths and random bytes on Modbus/TCP (pymodbus drops a buffer past the longest frame
whole), bytes with no valid CRC on Modbus RTU over a pty (hil.sim.rtu_gate).  The emulator's servers share one event
loop, so the Modbus floods are met by a Modbus/TCP client, the RTU one from another wire of the same process.

Counted, not timed: how fast the junk is dropped and how much a flood slows the other client (its median latency
against idle, target ≤ 2×) are a benchmark's figures, measured against a baseline in the same run
(benchmarks/bench_floods.py)."""

from __future__ import annotations

import asyncio
import socket
import subprocess
import sys
from collections.abc import Callable

import pytest

from hil.families.fbs.protocol.fatek import ETX, FrameAssembler, Loopback, check_reply, encode_request
from hil.families.fbs.transport.modbus import ModbusTransport
from hil.sim import rtu_gate
from hil.sim.rtu_gate import MAX_FRAME, RtuGate
from tests.conftest import EMULATOR_BENCH
from tests.external import emulate_process

FLOOD_MB = 100
#: a hang guard on every wait for a reply or for the flooding process: generous, never a measure
HANG_GUARD = 60.0
#: the flood has put this many MB on the wire before the other client starts (the server is reading junk by then)
GO_MB = 8
#: the other client's requests while the flood goes on (the flood stops only when they are all answered)
DURING = 50
#: the flooding process's loop: ``chunk`` (1 MB of junk) through ``send`` until a line on its stdin says stop; "go"
#: once GO_MB are sent; at the end the MB sent.  Each flood script defines ``chunk`` and ``send`` and fills in the pace
FLOOD_LOOP = """
import sys, threading, time
stop = threading.Event()
threading.Thread(target=lambda: (sys.stdin.readline(), stop.set()), daemon=True).start()
sent = 0
while not stop.is_set():
    send(chunk)
    sent += 1
    if sent == {go}:
        print("go", flush=True)
    {pace}
print(sent, flush=True)
"""
FLOOD = """
import socket, sys
host, port = sys.argv[1].rsplit(":", 1)
s = socket.create_connection((host, int(port)))
chunk = b"\\x02" * (1 << 20)
send = s.sendall
""" + FLOOD_LOOP.format(go=GO_MB, pace="pass") + """
s.shutdown(socket.SHUT_WR)
s.recv(1)
"""


class _CountingBuffer(bytearray):
    """The assembler's buffer, counting its searches and how many bytes each of them may scan."""

    searches = 0
    scannable = 0

    def _count(self, start: int | None, end: int | None) -> None:
        self.searches += 1
        self.scannable += (len(self) if end is None else min(end, len(self))) - (start or 0)

    def find(self, sub, start=None, end=None):
        self._count(start, end)
        return super().find(sub, start, end)

    def rfind(self, sub, start=None, end=None):
        self._count(start, end)
        return super().rfind(sub, start, end)


def test_an_stx_flood_is_dropped_in_linear_time():
    """Each 64 kB of STX costs a few searches of the buffer (it was one pass per STX: quadratic), and the buffer
    never keeps more than a frame's worth."""
    assembler = FrameAssembler()
    buffer = assembler._buf = _CountingBuffer()
    fed = 0
    for _ in range(FLOOD_MB * 16):
        before = buffer.searches
        assembler.feed(b"\x02" * 65536)
        fed += 65536
        assert buffer.searches - before <= 6, f"{buffer.searches - before} searches for one 64 kB read"
        assert assembler.pending <= 1  # only the last STX (a frame may start there)
    frames = assembler.feed(encode_request(1, Loopback("OK")))
    assert len(frames) == 1 and assembler.dropped >= FLOOD_MB << 20
    assert buffer.scannable <= 4 * fed, f"{buffer.scannable} bytes searched for {fed} fed"


def test_rtu_junk_is_dropped_in_linear_time(monkeypatch):
    """A constant amount of CRC work per read, however much junk came before it (it was quadratic: a CRC over the
    whole buffer per read, then one per start position at the silence — 64 kB blocked the emulator's loop for over
    5 minutes), a bounded buffer and one timer for the whole flood, not one per read."""
    chunk = bytes((i * 7 + 3) & 0xFF for i in range(4096))
    checked: list[int] = []  # bytes of each CRC check (is_frame) and each backward pass (last_frame)
    is_frame, last_frame = rtu_gate.is_frame, rtu_gate.last_frame
    monkeypatch.setattr(rtu_gate, "is_frame", lambda data: (checked.append(len(data)), is_frame(data))[1])
    monkeypatch.setattr(rtu_gate, "last_frame", lambda data: (checked.append(len(data)), last_frame(data))[1])
    loop = asyncio.new_event_loop()
    try:
        forwarded: list[bytes] = []
        gate = RtuGate(loop, forwarded.append)
        megabytes = 64
        for _ in range(megabytes * 256):
            gate.feed(chunk)
            assert len(gate._buffer) <= MAX_FRAME
        timers = len(loop._scheduled)
        gate._flush()
        gate.close()
    finally:
        loop.close()
    assert forwarded == [] and gate.stats["rtu_noise_bytes"] == megabytes << 20
    assert timers == 1, f"{timers} timers for {megabytes * 256} reads"
    assert max(checked) <= MAX_FRAME, f"a CRC over {max(checked)} bytes"
    assert sum(checked) <= MAX_FRAME * (megabytes * 256 + 1), f"{sum(checked)} bytes CRC'd for {megabytes} MB"


def _fatek_ping() -> tuple[bytes, Callable[[bytes], bool], Callable[[bytes], bool]]:
    """The request, when its reply is complete, and whether that reply is the right answer."""
    return (encode_request(1, Loopback("PING")), lambda got: got.endswith(bytes([ETX])),
            lambda got: check_reply(got, 1, Loopback.code) == "PING")


def _modbus_read() -> tuple[bytes, Callable[[bytes], bool], Callable[[bytes], bool]]:
    """FC03 of R0 ×1 (the emulator answers at the end of a scan, as the FATEK loop-back above)."""
    return (bytes.fromhex("000100000006010300000001"),
            lambda got: len(got) >= 6 and len(got) >= 6 + int.from_bytes(got[4:6], "big"),
            lambda got: got[:2] == b"\x00\x01" and got[6:9] == b"\x01\x03\x02" and len(got) == 11)


def _answered(sock: socket.socket, n: int, request=_fatek_ping) -> int:
    """``n`` requests one after another on ``sock``, each waiting for its whole reply (a hang guard on each): how
    many were answered right."""
    frame, complete, right = request()
    sock.settimeout(HANG_GUARD)
    good = 0
    for _ in range(n):
        sock.sendall(frame)
        got = b""
        while not complete(got):
            try:
                data = sock.recv(4096)
            except TimeoutError:
                raise AssertionError(f"hang guard: no reply within {HANG_GUARD:.0f} s (got {got!r})") from None
            assert data, f"the server closed the other client's connection (got {got!r})"
            got += data
        good += right(got)
    return good


def _flood(script: str, where: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", script, where], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True)
    assert proc.stdout.readline().strip() == "go", "the flood did not start"
    return proc


def _stop(flood: subprocess.Popen) -> int:
    """Tell the flood to stop; the MB it sent."""
    assert flood.poll() is None, f"the flood ended by itself (exit {flood.returncode}) before it was told to"
    try:
        out, _ = flood.communicate("stop\n", timeout=HANG_GUARD)
    except subprocess.TimeoutExpired:
        flood.kill()
        flood.communicate()
        raise AssertionError(f"hang guard: the flood did not stop within {HANG_GUARD:.0f} s") from None
    assert flood.returncode == 0, out
    return int(out.split()[-1])


@pytest.mark.e2e
def test_a_flood_on_one_connection_leaves_another_client_served(tmp_path):
    profile = tmp_path / "emulated.toml"
    profile.write_text(EMULATOR_BENCH.read_text())
    with emulate_process(profile, 1, {"fatek-tcp": "--fatek-tcp"}) as where:
        host, port = where["fatek-tcp"].rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=HANG_GUARD) as sock:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            assert _answered(sock, 5) == 5  # idle
            flood = _flood(FLOOD, where["fatek-tcp"])
            try:
                during = _answered(sock, DURING)  # the flood goes on until these are answered
            finally:
                sent = _stop(flood)
            assert during == DURING, f"{DURING - during} of {DURING} answered wrong during the flood"
            print(f"FATEK: {DURING} requests answered while the flood sent {sent} MB of STX")
            assert _answered(sock, 5) == 5  # and after it


# Sent at 100 MB/s, faster than a PLC Ethernet module's 100 Mbit/s port can carry (unpaced, pymodbus drops it
# within a twentieth of a second: the other client would hardly meet it).
MODBUS_FLOODS = {
    "tcp": """
import random, socket, sys
host, port = sys.argv[1].rsplit(":", 1)
s = socket.create_connection((host, int(port)))
rng = random.Random(1)
bogus = b"\\x00\\x01\\x00\\x00\\xff\\xff\\x01\\x03"  # an MBAP header announcing 65535 bytes
chunk = b"".join(bogus + bytes(rng.randrange(256) for _ in range(rng.randrange(300))) for _ in range(8000))
chunk = chunk[:1 << 20]
send = s.sendall
""" + FLOOD_LOOP.format(go=GO_MB, pace="time.sleep(0.01)") + """
s.shutdown(socket.SHUT_WR)
s.recv(1)
""",
    "rtu": """
import os, sys, tty
fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
tty.setraw(fd)
chunk = bytes((i * 7 + 3) & 0xFF for i in range(1 << 20))  # no valid CRC anywhere (test_rtu_junk_…)

def send(data):
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]
""" + FLOOD_LOOP.format(go=GO_MB, pace="time.sleep(0.01)") + """
os.close(fd)
""",
}


@pytest.mark.e2e
@pytest.mark.parametrize("wire", sorted(MODBUS_FLOODS))
def test_a_modbus_flood_leaves_another_client_served(tmp_path, wire):
    profile = tmp_path / "emulated.toml"
    profile.write_text(EMULATOR_BENCH.read_text())
    wires = {"modbus-tcp": "--modbus-tcp", **({"modbus-rtu": "--modbus-rtu"} if wire == "rtu" else {})}
    with emulate_process(profile, 1, wires) as where:
        host, port = where["modbus-tcp"].rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=HANG_GUARD) as sock:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            assert _answered(sock, 5, request=_modbus_read) == 5  # idle
            flood = _flood(MODBUS_FLOODS[wire], where[f"modbus-{wire}"])
            try:
                during = _answered(sock, DURING, request=_modbus_read)  # the flood goes on until these are answered
            finally:
                sent = _stop(flood)
            assert during == DURING, f"{DURING - during} of {DURING} answered wrong during the flood"
            print(f"Modbus {wire}: {DURING} requests answered while the flood sent {sent} MB of junk")
        # the reply timeouts hang guards: a new connection is served…
        with ModbusTransport.tcp(host, int(port), unit=1, timeout=HANG_GUARD) as plc:
            r0 = plc.read_words("R0", 4)
        if wire == "rtu":  # …and so is the line the junk came on
            with ModbusTransport.rtu(where["modbus-rtu"], unit=1, timeout=HANG_GUARD) as plc:
                assert plc.read_words("R0", 4) == r0
