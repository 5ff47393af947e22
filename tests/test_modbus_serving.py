"""The emulator served over Modbus (TCP and RTU over a pty) with pymodbus's real server, reached with
ModbusTransport (pymodbus's real sync clients).  Loopback with OS-chosen ports and real ptys; no mocks."""

from __future__ import annotations

import os
import random
import socket
import struct
import threading
import time
from collections.abc import Iterator

import pytest
import serial
from pymodbus.client import ModbusTcpClient

from hil.core.errors import PlcErrorReply, ReplyTimeout, TransportError, UnreachableAddress
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.sim.serve_modbus import start_modbus_rtu_pty, start_modbus_tcp
from hil.families.fbs.transport.modbus import ModbusTransport
from hil.sim.runtime import ServerHandle
from tests.concurrency import run_clients

WIRES = ["tcp", "rtu"]
#: a reply timeout where no reply is meant to be waited out: a hang guard, long enough for any busy host
HANG_GUARD = 30.0


def _start(emulator: Emulator, wire: str, unit: int = 1) -> ServerHandle:
    return start_modbus_tcp(emulator, unit=unit) if wire == "tcp" else start_modbus_rtu_pty(emulator, unit=unit)


def _connect(server: ServerHandle, **kwargs: object) -> ModbusTransport:
    kwargs.setdefault("timeout", HANG_GUARD)  # no test here waits a reply out unless it says so
    if server.kind == "modbus-tcp":
        host, _, port = server.address.rpartition(":")
        return ModbusTransport.tcp(host, int(port), **kwargs)
    return ModbusTransport.rtu(server.address, **kwargs)


@pytest.fixture
def emulator() -> Emulator:
    return Emulator()


@pytest.fixture(params=WIRES)
def server(request: pytest.FixtureRequest, emulator: Emulator) -> Iterator[ServerHandle]:
    handle = _start(emulator, request.param)
    yield handle
    handle.stop()


@pytest.fixture
def plc(server: ServerHandle) -> Iterator[ModbusTransport]:
    transport = _connect(server)
    yield transport
    transport.close()


@pytest.fixture
def tcp_server(emulator: Emulator) -> Iterator[ServerHandle]:
    handle = start_modbus_tcp(emulator)
    yield handle
    handle.stop()


def _tcp_address(handle: ServerHandle) -> tuple[str, int]:
    host, _, port = handle.address.rpartition(":")
    return host, int(port)


# -- round trips ---------------------------------------------------------------------------------------------------
def test_words_round_trip(plc: ModbusTransport, emulator: Emulator) -> None:
    plc.write_words("R100", [1, 0xFFFF, 0x1234])
    assert emulator.memory.read("R100", 3) == [1, 0xFFFF, 0x1234]
    plc.write_words("D2990", list(range(9)))  # up to D2998, the last mapped D
    assert emulator.memory.read("D2990", 9) == list(range(9))
    plc.write("R5998", 77)
    assert emulator.memory.get("R5998") == 77
    emulator.service(lambda mem: mem.write("R4128", [5, 6, 7, 8, 9, 10, 11]))
    assert plc.read_words("R4128", 7) == [5, 6, 7, 8, 9, 10, 11]
    emulator.service(lambda mem: (mem.set("RT12", 300), mem.set("RC199", 4)))
    assert plc.read("RT12") == 300 and plc.read("RC199") == 4
    plc.write("RC0", 9)
    assert emulator.memory.get("RC0") == 9


def test_bits_round_trip(plc: ModbusTransport, emulator: Emulator) -> None:
    for bank, last in (("Y", 255), ("X", 255), ("M", 2001), ("S", 999), ("T", 255), ("C", 255)):
        plc.write_bits(f"{bank}{last - 2}", [1, 0, 1])
        assert emulator.memory.read(f"{bank}{last - 2}", 3) == [1, 0, 1], bank
        assert plc.read_bits(f"{bank}{last - 3}", 4) == [0, 1, 0, 1], bank
    plc.write("M1952", 1)
    assert emulator.memory.get("M1952") == 1 and plc.read("M1952") == 1
    plc.write("WY8", 0xA5C3)
    assert emulator.memory.get("WY8") == 0xA5C3
    assert plc.read("WY8") == 0xA5C3
    emulator.service(lambda mem: mem.set("DWM32", 0x80000001))
    assert plc.read("DWM32") == 0x80000001


def test_32bit_counters_round_trip(plc: ModbusTransport, emulator: Emulator) -> None:
    plc.write("DRC200", 0x12345678)
    plc.write("DRC255", 0xFFFFFFFF)
    assert emulator.memory.get("DRC200") == 0x12345678
    assert emulator.memory.get("DRC255") == 0xFFFFFFFF
    emulator.service(lambda mem: mem.set("DRC201", 0x00010002))
    assert plc.read_words("DRC200", 2) == [0x12345678, 0x00010002]
    # the wire layout: two holding registers, low word first
    assert plc.read_words("DR0", 1) == [0]
    plc.write("DR10", 0xBEEF0001)
    assert emulator.memory.read("R10", 2) == [0x0001, 0xBEEF]


def test_mixed_read_and_write(plc: ModbusTransport, emulator: Emulator) -> None:
    before = plc.requests
    plc.write_many([("R7", 70), ("R8", 80), ("M100", 1), ("DRC210", 123456), ("D5", 5), ("WX0", 0x00FF)])
    assert plc.requests - before == 5  # R7+R8 share one FC16; the rest differ in table or are not adjacent
    mem = emulator.memory
    assert (mem.get("R7"), mem.get("R8"), mem.get("M100"), mem.get("DRC210"), mem.get("D5")) == (70, 80, 1, 123456, 5)
    assert mem.read("X0", 9) == [1] * 8 + [0]
    before = plc.requests
    values = plc.read_many(["R8", "M100", "R7", "DRC210", "X7", "X8", "D5", "WX0", "R9"])
    assert values == [80, 1, 70, 123456, 1, 0, 5, 0x00FF, 0]
    assert plc.requests - before == 5  # coils X0–X15, coil M100, holding R7–R9, D5, DRC210


def _reads(plc: ModbusTransport, n: int) -> int:
    """Requests the server sees for ``n`` reads (on RTU each is followed by its fence, a probe read)."""
    return plc.requests_per_read * n


def test_large_transfers_split_at_the_modbus_limits(plc: ModbusTransport, emulator: Emulator) -> None:
    emulator.service(lambda mem: mem.write("R0", [i * 3 & 0xFFFF for i in range(300)]))
    before = emulator.stats["modbus_requests"]
    assert plc.read_words("R0", 300) == [i * 3 & 0xFFFF for i in range(300)]
    assert emulator.stats["modbus_requests"] - before == _reads(plc, 3)  # 125 + 125 + 50 (FC03 limit 125)

    before = emulator.stats["modbus_requests"]
    plc.write_words("D0", [i + 1 for i in range(246)])
    assert emulator.memory.read("D0", 246) == [i + 1 for i in range(246)]
    assert emulator.stats["modbus_requests"] - before == 2  # 123 + 123 (FC16 limit 123)

    before = emulator.stats["modbus_requests"]
    pattern = [(i * 7) % 3 == 0 for i in range(2002)]
    plc.write_bits("M0", pattern)
    assert emulator.memory.read("M0", 2002) == [int(b) for b in pattern]
    assert emulator.stats["modbus_requests"] - before == 2  # 1968 + 34 (FC15 limit 1968)

    before = emulator.stats["modbus_requests"]
    assert plc.read_bits("M0", 2002) == [int(b) for b in pattern]
    assert emulator.stats["modbus_requests"] - before == _reads(plc, 2)  # 2000 + 2 (FC01 limit 2000)


def test_status_proves_the_plc_answers(plc: ModbusTransport, emulator: Emulator) -> None:
    before = emulator.stats["modbus_requests"]
    status = plc.status()
    assert status.running is None and status.via == "modbus"
    assert emulator.stats["modbus_requests"] - before == _reads(plc, 1)
    assert status.identity["unit"] == "1"


# -- refusals and errors ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("call", [
    lambda t: t.read("D4054"),
    lambda t: t.write("D4053", 1),
    lambda t: t.read_words("R4100", 100),  # the part below R4168 must not be sent either
    lambda t: t.read_words("R4000", 300),  # would be several requests: refused before the first
    lambda t: t.write_words("D2990", [1] * 10),
    lambda t: t.read_many(["R0", "M0", "R6000"]),
    lambda t: t.write_many([("R0", 1), ("R4168", 1)]),
])
def test_out_of_map_raises_and_sends_nothing(plc: ModbusTransport, server: ServerHandle, emulator: Emulator,
                                             call) -> None:
    snapshot = emulator.memory.snapshot()
    requests, sent = emulator.stats["modbus_requests"], plc.requests
    wire = dict(server.ptys.stats) if server.kind == "modbus-rtu" else None
    with pytest.raises(UnreachableAddress, match="default FBs Modbus map"):
        call(plc)
    assert emulator.stats["modbus_requests"] == requests and plc.requests == sent
    assert emulator.memory.snapshot() == snapshot
    if wire is not None:
        assert dict(server.ptys.stats) == wire  # not one byte crossed the pty
    assert plc.unreachable_reason("D4054") and plc.unreachable_reason("R0") is None


def test_server_refuses_unmapped_addresses_with_exception_2(tcp_server: ServerHandle, emulator: Emulator) -> None:
    # checked with a raw pymodbus client over TCP; the gate is the same for both wires
    host, port = _tcp_address(tcp_server)
    with ModbusTcpClient(host, port=port, timeout=HANG_GUARD, retries=0) as client:
        for read in (lambda: client.read_coils(256, count=1), lambda: client.read_coils(990, count=20),
                     lambda: client.read_coils(1250, count=10), lambda: client.read_holding_registers(4168),
                     lambda: client.read_holding_registers(8999), lambda: client.read_holding_registers(4160, count=9),
                     lambda: client.write_register(4168, 1), lambda: client.write_coils(4000, [True] * 3)):
            rr = read()
            assert rr.isError() and rr.exception_code == 2
        rr = client.read_discrete_inputs(0, count=1)
        assert rr.isError() and rr.exception_code == 1  # the FBs has no discrete inputs: X are coils
    with socket.create_connection((host, port), timeout=HANG_GUARD) as s:  # pymodbus's client refuses to send this
        s.sendall(_mbap_read(5, 1, 0, 126))
        # pymodbus 3.16 rejects the quantity while decoding, before the gate, and answers "function 0x80,
        # exception 1" rather than the standard 0x83/3; what matters here: an exception, and nothing read.
        tid, _, length, unit, fc, code = struct.unpack(">HHHBBB", _recv_exactly(s, 9))
        assert (tid, length, unit) == (5, 3, 1) and fc & 0x80 and code in (1, 3)
    assert emulator.stats["modbus_exception_2"] == 8
    assert emulator.memory.get("M2000") == 0 and emulator.memory.get("M2001") == 0


def test_exception_reply_becomes_plc_error_reply(tcp_server: ServerHandle) -> None:
    host, port = _tcp_address(tcp_server)
    with (
        ModbusTransport.tcp(host, port, unit=7, timeout=HANG_GUARD) as other_unit,
        pytest.raises(PlcErrorReply) as info,
    ):
        other_unit.read("R4128")
    message = str(info.value)
    assert info.value.code == "11" and "gateway target device failed to respond" in message
    assert "FC03" in message and "4128" in message and f"{port}?unit=7" in message
    assert "serves no unit 7 — check the target's ?unit=" in message  # the likeliest cause, said (RTU and FATEK do)


def test_silence_becomes_reply_timeout(emulator: Emulator) -> None:
    server = start_modbus_rtu_pty(emulator, unit=1)
    try:
        with ModbusTransport.rtu(server.address, unit=9, timeout=0.2, retries=1) as wrong_unit:
            sent: list[bytes] = []
            wrong_unit.observers.append(lambda direction, frame: sent.append(frame) if direction == "tx" else None)
            with pytest.raises(ReplyTimeout) as info:
                wrong_unit.read_words("D10", 2)
        message = str(info.value)
        assert "FC03" in message and "6010 ×2" in message and "D10–D11" in message
        assert server.address in message and "unit=9" in message and "0.4 s" in message
        # two tries, counted (not timed): the read and the probe read that would have resynchronised the line
        assert [(frame[0], frame[1]) for frame in sent] == [(9, 3), (9, 3)], sent
        with _connect(server) as right_unit:  # the server is fine for its own unit
            assert right_unit.read("D10") == 0
        # answered after both tries (the line is served in order): each of them reached the server, ignored
        assert emulator.stats["modbus_ignored"] == 2
    finally:
        server.stop()


def test_connection_refused_is_a_transport_error_with_a_hint() -> None:
    with socket.socket() as probe:  # a port that was free a moment ago and has nobody listening
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with pytest.raises(TransportError, match=f"cannot connect to modbus\\+tcp://127.0.0.1:{port}.*reachable"):
        ModbusTransport.tcp("127.0.0.1", port, timeout=0.5)
    with pytest.raises(TransportError, match="/dev/no-such-tty"):
        ModbusTransport.rtu("/dev/no-such-tty", timeout=0.5)


def test_stop_frees_the_port_and_closes_the_ptys(emulator: Emulator) -> None:
    tcp = start_modbus_tcp(emulator)
    host, port = _tcp_address(tcp)
    tcp.stop()
    tcp.stop()  # idempotent
    with pytest.raises(TransportError):
        ModbusTransport.tcp(host, port, timeout=0.5)
    with socket.socket() as again:  # the port is really free
        again.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        again.bind((host, port))

    fds = set(os.listdir("/proc/self/fd"))
    rtu = start_modbus_rtu_pty(emulator)
    path = rtu.address
    with _connect(rtu) as plc:
        plc.write("R0", 1)
    rtu.stop()
    rtu.stop()
    # both ptys and the server's port are closed: nothing opened since is still open (another thread of this
    # worker may close one of its own meanwhile: only what is new counts)
    assert not set(os.listdir("/proc/self/fd")) - fds
    assert not os.path.exists(path) or _cannot_talk(path)


def _cannot_talk(path: str) -> bool:
    try:
        with ModbusTransport.rtu(path, timeout=0.2, retries=0) as t:
            t.read("R0")
    except (TransportError, OSError):
        return True
    return False


# -- robustness --------------------------------------------------------------------------------------------------
def _mbap_read(tid: int, unit: int, address: int, count: int) -> bytes:
    return struct.pack(">HHHBBHH", tid, 0, 6, unit, 3, address, count)


def test_tcp_server_survives_garbage_partial_frames_and_hangups(tcp_server: ServerHandle,
                                                                emulator: Emulator) -> None:
    host, port = _tcp_address(tcp_server)
    frame = _mbap_read(1, 1, 100, 2)
    # garbage, then hang up
    with socket.create_connection((host, port), timeout=HANG_GUARD) as s:
        s.sendall(os.urandom(300))
    # a partial frame, then hang up mid-frame
    with socket.create_connection((host, port), timeout=HANG_GUARD) as s:
        s.sendall(frame[:5])
    # a header that promises more than it sends, then hang up
    with socket.create_connection((host, port), timeout=HANG_GUARD) as s:
        s.sendall(struct.pack(">HHHB", 9, 0, 200, 1) + b"\x03\x00")
    # a request sent in two pieces is still one request
    with socket.create_connection((host, port), timeout=HANG_GUARD) as s:
        emulator.service(lambda mem: mem.write("R100", [0xAAAA, 0x5555]))
        s.sendall(frame[:7])
        time.sleep(0.05)  # to part the pieces on the wire, not to wait for anything: a slow host may only join them
        s.sendall(frame[7:])
        reply = _recv_exactly(s, 13)
        assert struct.unpack(">HHHBBBHH", reply) == (1, 0, 7, 1, 3, 4, 0xAAAA, 0x5555)
    # a request, then hang up before reading the reply
    with socket.create_connection((host, port), timeout=HANG_GUARD) as s:
        s.sendall(_mbap_read(2, 1, 0, 125))
    # the server still serves
    with _connect(tcp_server) as plc:
        plc.write("R1", 42)
        assert plc.read_words("R100", 2) == [0xAAAA, 0x5555]
    assert emulator.memory.get("R1") == 42


def _recv_exactly(s: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = s.recv(n - len(data))
        assert chunk, f"connection closed after {len(data)} of {n} bytes"
        data += chunk
    return data


def test_eight_parallel_tcp_clients(tcp_server: ServerHandle, emulator: Emulator) -> None:
    rounds = 40
    start = threading.Barrier(8)

    def client(n: int) -> None:
        with _connect(tcp_server) as plc:
            start.wait(timeout=60)  # a hang guard
            for i in range(rounds):
                words = [n * 1000 + i, i, n]
                plc.write_words(f"D{n * 10}", words)
                plc.write(f"M{n * 8 + i % 8}", 1)
                assert plc.read_words(f"D{n * 10}", 3) == words
                assert plc.read(f"M{n * 8 + i % 8}") == 1

    run_clients(client, 8, join_timeout=60)  # a hang guard
    for n in range(8):
        assert emulator.memory.read(f"D{n * 10}", 3) == [n * 1000 + rounds - 1, rounds - 1, n]
    assert emulator.memory.read("M0", 64) == [1] * 64
    assert emulator.stats["modbus_requests"] >= 8 * rounds * 4
    with _connect(tcp_server) as plc:  # and still serves afterwards
        assert plc.read("D70") == 7000 + rounds - 1


def test_rtu_server_survives_garbage_and_client_hangups(emulator: Emulator) -> None:
    server = start_modbus_rtu_pty(emulator)
    try:
        noise = random.Random(7).randbytes(64)
        for junk in (noise, b"\x01\x03\x00", b"\x01\x10\x00\x00\x00\x02\x04\x00"):
            with serial.Serial(server.address, timeout=0.1) as raw:
                raw.write(junk)
                raw.flush()
            time.sleep(0.02)  # a silence on the line (a frame gap is 4 ms), not a wait: a slow host only lengthens it
            # the line is cut into frames at silences and noise is dropped, as a real RTU slave does:
            # the very next request gets through without a retry (the reply timeout a hang guard)
            with ModbusTransport.rtu(server.address, timeout=HANG_GUARD, retries=0) as plc:
                plc.write("R3", 33)
                assert plc.read("R3") == 33
        # several clients one after another: a hang-up never ends the session for the next
        for i in range(3):
            with _connect(server) as plc:
                plc.write("D1", i)
        assert emulator.memory.get("D1") == 2
        assert server.ptys.stats["rtu_noise_bytes"] >= 64 + 3 + 8
    finally:
        server.stop()
