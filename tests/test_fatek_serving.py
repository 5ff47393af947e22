"""FatekTransport against the emulator's FATEK server, over real TCP sockets on 127.0.0.1 and real ptys.

No mocks: every byte crosses a kernel socket or pty.  The second half feeds the server bad input on raw
connections and shows it keeps serving, counts the rejects and never lets a rejected frame touch memory.
"""

from __future__ import annotations

import asyncio
import errno
import fcntl
import os
import socket
import struct
import termios
import threading
import time
from dataclasses import dataclass
from typing import ClassVar

import pytest
import serial

from hil.core.errors import PlcErrorReply, ReplyTimeout, TransportError
from hil.families.fbs.address import parse
from hil.families.fbs.protocol.fatek import (
    Command,
    FrameAssembler,
    MixedWrite,
    ReadRegisters,
    WriteRegisters,
    build_frame,
    encode_error,
    encode_request,
    split_frame,
)
from hil.families.fbs.sim import serve_fatek
from hil.families.fbs.sim.plc import OS_VERSION, UNIT_TYPE_MC, Emulator
from hil.families.fbs.sim.serve_fatek import start_fatek_pty, start_fatek_tcp
from hil.families.fbs.transport.fatek import FatekTransport
from hil.io.line import open_hint
from hil.sim.runtime import LoopThread
from tests.concurrency import run_clients

STATUS_REQUEST = b"\x020140C7\x03"
#: a reply timeout where no reply is meant to be waited out: a hang guard, long enough for any busy host
HANG_GUARD = 30.0


# --- fixtures -------------------------------------------------------------------------------------------------------
@pytest.fixture
def emulator() -> Emulator:
    return Emulator()


@pytest.fixture
def tcp(emulator):
    handle = start_fatek_tcp(emulator)
    yield handle
    handle.stop()


@pytest.fixture
def pty(emulator):
    handle = start_fatek_pty(emulator)
    yield handle
    handle.stop()


@pytest.fixture(params=["tcp", "pty"])
def client(request, emulator):
    handle = (start_fatek_tcp if request.param == "tcp" else start_fatek_pty)(emulator)
    url = f"socket://{handle.address}" if request.param == "tcp" else handle.address
    transport = FatekTransport(url, timeout=HANG_GUARD)
    yield transport
    transport.close()
    handle.stop()


def _tcp_address(handle) -> tuple[str, int]:
    host, _, port = handle.address.rpartition(":")
    return host, int(port)


class RawTcp:
    """A bare socket client: send any bytes, collect reply frames."""

    def __init__(self, handle) -> None:
        self.sock = socket.create_connection(_tcp_address(handle), timeout=HANG_GUARD)
        self.assembler = FrameAssembler()

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def frames(self, n: int = 1, timeout: float = HANG_GUARD) -> list[bytes]:
        """Up to ``n`` frames, waiting at most ``timeout`` s for them (a hang guard, or how long "nothing else"
        is looked for)."""
        got: list[bytes] = []
        deadline = time.monotonic() + timeout
        while len(got) < n and (left := deadline - time.monotonic()) > 0:
            self.sock.settimeout(left)
            try:
                data = self.sock.recv(4096)
            except TimeoutError:
                break
            if not data:
                break
            got += self.assembler.feed(data)
        return got

    def exchange(self, frame: bytes) -> bytes:
        self.send(frame)
        replies = self.frames(1)
        assert len(replies) == 1, f"hang guard: no reply within {HANG_GUARD:.0f} s"
        return replies[0]

    def close(self) -> None:
        self.sock.close()


def _bad_checksum(frame: bytes) -> bytes:
    return frame[:-3] + (b"00" if frame[-3:-1] != b"00" else b"11") + frame[-1:]


@dataclass
class UnknownCommand(Command):
    """A command code the PLC does not know, to see error 4 come back through the client."""

    code: ClassVar[str] = "99"


# --- round trips over both wires -------------------------------------------------------------------------------------
def test_words_round_trip(client, emulator):
    client.write_words("R4128", [0x1234, 0, 0xFFFF])
    assert client.read_words("R4128", 3) == [0x1234, 0, 0xFFFF]
    assert emulator.memory.read("R4128", 3) == [0x1234, 0, 0xFFFF]
    client.write("D4054", 777)
    assert client.read("D4054") == 777


def test_bits_round_trip(client, emulator):
    client.write_bits("Y0", [1, 0, 1, 1])
    assert client.read_bits("Y0", 4) == [1, 0, 1, 1]
    client.write("M1952", 1)
    assert client.read("M1952") == 1 and emulator.memory.get("M1952") == 1
    client.write("WM800", 0xA5A5)
    assert client.read_bits("M800", 16) == [(0xA5A5 >> i) & 1 for i in range(16)]


def test_32_bit_round_trip(client, emulator):
    client.write("DR100", 0x12345678)
    client.write("DD200", 0xFFFFFFFF)
    client.write_words("DRC200", [1, 0x80000000, 70000])
    assert client.read("DR100") == 0x12345678
    assert emulator.memory.read("R100", 2) == [0x5678, 0x1234]  # low word first, as address.LOW_WORD_FIRST says
    assert client.read("DD200") == 0xFFFFFFFF
    assert client.read_words("DRC200", 3) == [1, 0x80000000, 70000]


def test_mixed_read_and_write(client):
    client.write_many({"R5": 5, "M7": 1, "DR10": 0x10001, "WY8": 0x00FF})
    assert client.read_many(["R5", "M7", "DR10", "WY8", "Y8", "Y16"]) == [5, 1, 0x10001, 0x00FF, 1, 0]


def test_large_requests_are_split(client, emulator):
    before = client.requests
    client.write_words("R1000", list(range(200)))
    assert client.requests - before == 4  # 64 + 64 + 64 + 8
    assert client.read_words("R1000", 200) == list(range(200))
    bits = [(i * 7) % 3 == 0 for i in range(600)]
    client.write_bits("M0", bits)
    assert client.read_bits("M0", 600) == [int(b) for b in bits]
    assert client.requests - before == 4 + 4 + 3 + 3
    names = [f"R{i}" for i in range(2000, 2100)]
    client.write_many({n: i for i, n in enumerate(names)})  # 100 words → 4 mixed writes of ≤ 32
    assert client.read_many(names) == list(range(100))  # → 2 mixed reads of ≤ 64
    assert emulator.memory.read("R2000", 100) == list(range(100))


def test_status_and_identity(client, emulator):
    status = client.status()
    assert status.running is True and "RUN" in status.flags
    assert status.identity["unit type"].startswith("01") and status.identity["os version"] == "V4.0x"
    assert status.identity["R size"] == "8072"
    ident = client.identity()
    assert (ident.unit_type, ident.os_version) == (UNIT_TYPE_MC, OS_VERSION)
    assert ident.sizes["M"] == 2002 and ident.sizes["D"] == 4096
    client.set_running(False)
    assert emulator.running is False and client.status().running is False
    client.set_running(True)
    assert client.status().running is True


def test_bit_actions_and_enable_state(client, emulator):
    client.bit_action("M5", 1)  # disable
    client.bit_action("M5", 3)  # set — a disabled bit can still be forced
    assert client.read_disabled("M0", 8) == [0, 0, 0, 0, 0, 1, 0, 0]
    assert emulator.memory.disabled["M"][5] == 1 and emulator.memory.get("M5") == 1
    client.bit_action("M5", 4)
    client.bit_action("M5", 2)
    assert client.read_disabled("M5") == [0] and client.read("M5") == 0


def test_loopback(client):
    assert client.loopback("HELLO FBs 0123") == "HELLO FBs 0123"


def test_unknown_command_through_the_client(client):
    with pytest.raises(PlcErrorReply) as info:
        client.request(UnknownCommand())
    assert info.value.code == "4" and "illegal format" in info.value.meaning
    assert "station 01" in str(info.value)


def test_observers_see_the_wire(client):
    trace: list[tuple[str, bytes]] = []
    client.observers.append(lambda direction, frame: trace.append((direction, frame)))
    client.read_words("R12", 3)
    assert trace[0] == ("tx", b"\x02014603R0001275\x03")
    assert trace[1][0] == "rx" and split_frame(trace[1][1]).data == "0" + "0000" * 3


# --- error replies on raw frames ------------------------------------------------------------------------------------
def test_out_of_model_address_gets_error_a(tcp, emulator):
    raw = RawTcp(tcp)
    try:
        assert raw.exchange(build_frame(1, "46", "01R99999")) == encode_error(1, "46", "A")
        assert raw.exchange(build_frame(1, "44", "05M1999")) == encode_error(1, "44", "A")  # runs past M2001
        assert raw.exchange(build_frame(1, "99", "")) == encode_error(1, "99", "4")
        assert raw.exchange(build_frame(1, "47", "02R0000012")) == encode_error(1, "47", "4")  # values cut short
    finally:
        raw.close()
    assert emulator.stats["fatek_error_A"] == 2 and emulator.stats["fatek_error_4"] == 2


def test_broadcast_is_executed_without_reply(tcp, emulator):
    raw = RawTcp(tcp)
    try:
        raw.send(encode_request(0, WriteRegisters(parse("R7"), [42])))
        assert raw.exchange(STATUS_REQUEST).startswith(b"\x020140")  # the only reply is the status
    finally:
        raw.close()
    assert emulator.memory.get("R7") == 42 and emulator.stats["fatek_broadcast"] == 1


# --- bad input: the server ignores it, counts it, keeps serving, and memory stays as it was ---------------------------
def test_rejected_frames_over_tcp(tcp, emulator):
    emulator.memory.set("R0", 1)
    snapshot = emulator.memory.snapshot()
    write = encode_request(1, WriteRegisters(parse("R0"), [0xBAD]))
    raw = RawTcp(tcp)
    try:
        raw.send(b"\xff\xfe garbage \x03\x03 more")  # no STX at all
        raw.send(_bad_checksum(write))
        raw.send(encode_request(2, WriteRegisters(parse("R0"), [0xBAD])))  # another station
        raw.send(write[:9])  # a frame cut short, then a new frame starts
        raw.send(b"\x02" + b"7" * 600 + b"\x03")  # over-long
        raw.send(b"\x02\x03")  # too short to be a frame
        for byte in STATUS_REQUEST:  # a good frame, one byte at a time
            raw.send(bytes([byte]))
        replies = raw.frames(1)
        assert len(replies) == 1 and split_frame(replies[0]).command == "40"
        # and nothing else was answered: a short look is enough, as a slow host can only make it miss a stray
        # reply, never invent one (the counters below are the real check: one request served)
        assert raw.frames(1, timeout=0.2) == []
    finally:
        raw.close()
    assert emulator.stats["fatek_bad_checksum"] == 1
    assert emulator.stats["fatek_wrong_station"] == 1
    assert emulator.stats["fatek_malformed"] == 2
    assert emulator.stats["fatek_garbage_bytes"] > 0
    assert emulator.stats["fatek_requests"] == 1
    assert emulator.memory.snapshot() == snapshot


def test_disconnect_mid_frame_then_serve_others(tcp, emulator):
    snapshot = emulator.memory.snapshot()
    for _ in range(5):
        raw = RawTcp(tcp)
        raw.send(encode_request(1, WriteRegisters(parse("R0"), [0xBAD]))[:-4])
        raw.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")  # RST
        raw.close()
    with FatekTransport(f"socket://{tcp.address}", timeout=HANG_GUARD) as client:
        assert client.read("R0") == 0
    assert emulator.memory.snapshot() == snapshot


def test_eight_parallel_clients(tcp, emulator):
    def work(n: int) -> None:
        with FatekTransport(f"socket://{tcp.address}", timeout=HANG_GUARD) as client:
            for i in range(30):
                client.write_words(f"R{100 * n}", [n, i, n * i])
                assert client.read_words(f"R{100 * n}", 3) == [n, i, n * i]

    run_clients(work, 8, join_timeout=60)  # a hang guard
    assert [emulator.memory.read(f"R{100 * n}", 3) for n in range(8)] == [[n, 29, n * 29] for n in range(8)]


def test_rejected_frames_over_pty(pty, emulator):
    snapshot = emulator.memory.snapshot()
    write = encode_request(1, WriteRegisters(parse("R0"), [0xBAD]))
    port = serial.Serial(pty.address, timeout=HANG_GUARD)  # read_until returns at the ETX
    try:
        port.write(b"noise\xff" + _bad_checksum(write) + encode_request(9, WriteRegisters(parse("R0"), [1])))
        port.write(write[:10])  # cut short by the next STX
        port.write(STATUS_REQUEST)
        reply = port.read_until(b"\x03")
        assert reply.endswith(b"\x03"), f"hang guard: no whole reply within {HANG_GUARD:.0f} s: {reply!r}"
        assert split_frame(reply).command == "40"
    finally:
        port.close()
    assert emulator.stats["fatek_bad_checksum"] == 1 and emulator.stats["fatek_wrong_station"] == 1
    assert emulator.memory.snapshot() == snapshot


def test_pty_survives_clients_closing_mid_frame(emulator, monkeypatch):
    # With no client open the server must idle, not spin on EIO from the master: counted as the times its reader
    # is called with nothing to read, over a number of its loop's iterations (a spinning reader is called on every
    # one of them; host time does not enter: its CPU time while idle is a benchmark's figure,
    # benchmarks/bench_host_time.py)
    empty_wakeups: list[int] = []
    readable = serve_fatek._PtyServer._readable

    def counting(self) -> None:
        try:
            waiting = struct.unpack("i", fcntl.ioctl(self.master, termios.FIONREAD, b"\0\0\0\0"))[0]
        except OSError:  # EIO: nothing to read either
            waiting = 0
        if not waiting:
            empty_wakeups.append(1)
        readable(self)

    monkeypatch.setattr(serve_fatek._PtyServer, "_readable", counting)
    pty = start_fatek_pty(emulator)
    try:
        for _ in range(3):
            port = serial.Serial(pty.address, timeout=1.0)
            port.write(encode_request(1, MixedWrite([(parse("R0"), 5)]))[:8])  # then go away mid-frame
            port.close()

        async def iterations(n: int) -> None:
            for _ in range(n):
                await asyncio.sleep(0)  # one pass of the loop each: a readable fd's reader is called in every one

        woken = len(empty_wakeups)
        LoopThread.shared().run(iterations(200), timeout=60)  # the timeout a hang guard
        # a spinning reader is called in each of the 200 passes; an idle one at most once per client gone (a flush
        # on close racing the read; 0 seen)
        idle_calls = len(empty_wakeups) - woken
        assert idle_calls <= 3, f"the reader was called {idle_calls} times with nothing to read in 200 passes"
        with FatekTransport(pty.address, timeout=HANG_GUARD) as client:
            assert client.read_words("R0", 2) == [0, 0]
            client.write("R1", 9)
        assert emulator.memory.get("R1") == 9
    finally:
        pty.stop()


def test_pty_server_does_not_talk_first(pty):
    port = serial.Serial(pty.address, timeout=0.2)
    try:
        assert port.read(1) == b""
    finally:
        port.close()


# --- client-side failures -------------------------------------------------------------------------------------------
def _sent(client: FatekTransport) -> list[bytes]:
    """The frames ``client`` puts on the wire from now on (its observers)."""
    frames: list[bytes] = []
    client.observers.append(lambda direction, frame: frames.append(frame) if direction == "tx" else None)
    return frames


def test_read_timeout_names_request_station_and_wait(tcp):
    with FatekTransport(f"socket://{tcp.address}", station=5, timeout=0.3, retries=0) as client:
        sent = _sent(client)
        started = time.monotonic()
        with pytest.raises(ReplyTimeout) as info:
            client.read_words("R12", 3)
        elapsed = time.monotonic() - started
    message = str(info.value)
    assert [split_frame(f).command for f in sent] == ["46"]  # one try, no retry (retries=0)
    # it waited its timeout out: a guaranteed lower bound (the client gives up only at its monotonic deadline; a
    # busy host only waits longer), and no upper one
    assert elapsed >= 0.3 - 1e-6
    assert "station 05" in message and "read 3 from R12 (46)" in message and "0.30 s" in message
    assert "054603R00012" in message and tcp.address in message


def test_reads_are_retried_and_writes_are_not(tcp):
    with FatekTransport(f"socket://{tcp.address}", station=5, timeout=0.2, retries=2) as client:
        sent = _sent(client)
        started = time.monotonic()
        with pytest.raises(ReplyTimeout, match="3 tries of 0.2 s"):
            client.read("R0")
        elapsed = time.monotonic() - started
        # three tries, counted: the read, then a resynchronising loop-back before each retry (unanswered too, so the
        # read was not sent again) — and each waited out its 0.2 s (a guaranteed lower bound, no upper one)
        assert [split_frame(f).command for f in sent] == ["46", "4E", "4E"]
        assert elapsed >= 3 * 0.2 - 1e-6
        # The line is suspect now (a late reply may come): a write is not sent until a loop-back resynchronises.
        sent.clear()
        with pytest.raises(ReplyTimeout, match="not sent .* went unanswered .* and so did a loop-back"):
            client.write("R0", 1)
        assert [split_frame(f).command for f in sent] == ["4E", "4E", "4E"], "loop-backs only: the write not sent"
    with FatekTransport(f"socket://{tcp.address}", station=5, timeout=0.2, retries=2) as client:
        sent = _sent(client)
        with pytest.raises(ReplyTimeout, match="outcome unknown") as info:
            client.write("R0", 1)
        assert "attempt 1 of 1" in str(info.value)
        assert [split_frame(f).command for f in sent] == ["47"], "one try: a write is never retried"


def test_timeout_mentions_bad_frames_discarded():
    """A peer that answers only with wrong frames: the client discards them and says so when it gives up."""
    listener = socket.create_server(("127.0.0.1", 0))
    port = listener.getsockname()[1]

    client_done = threading.Event()

    def peer() -> None:
        conn, _ = listener.accept()
        with conn:
            conn.recv(100)
            conn.sendall(_bad_checksum(encode_error(1, "46", "0")) + build_frame(2, "46", "00001")
                         + build_frame(1, "44", "00"))
            # the connection stays open until the client has given up (an event, not a sleep: a client slowed by
            # a busy host must see its timeout, not the peer hanging up)
            client_done.wait(60)  # a hang guard

    thread = threading.Thread(target=peer, daemon=True)
    thread.start()
    try:
        with (
            FatekTransport(f"socket://127.0.0.1:{port}", timeout=0.3, retries=0) as client,
            pytest.raises(ReplyTimeout) as info,
        ):
            client.read("R0")
    finally:
        client_done.set()
        thread.join(60)
        listener.close()
    message = str(info.value)
    assert "discarded 3 bad frame(s)" in message
    assert "ChecksumError" in message and "StationMismatch" in message and "CommandMismatch" in message


def test_server_gone_is_a_transport_error(emulator):
    handle = start_fatek_tcp(emulator)
    client = FatekTransport(f"socket://{handle.address}", timeout=0.5, retries=0)
    try:
        assert client.read("R0") == 0
        handle.stop()
        handle.stop()  # idempotent
        with pytest.raises(TransportError):
            client.read("R0")
            client.read("R0")  # a socket may accept one more write before the reset shows
    finally:
        client.close()


def test_opening_missing_device_is_explained():
    with pytest.raises(TransportError, match="no such device"):
        FatekTransport("/dev/does-not-exist-ttyUSB9")
    with pytest.raises(TransportError, match="cannot open socket://"):
        FatekTransport("socket://127.0.0.1:1")


def test_permission_hint():
    # Running as root cannot provoke EACCES on a device; the hint is chosen from the errno pyserial reports.
    exc = serial.SerialException(errno.EACCES, "could not open port /dev/ttyUSB0: [Errno 13] Permission denied")
    assert "dialout" in open_hint("/dev/ttyUSB0", exc)


def test_pty_slave_path_looks_like_a_device(pty):
    assert pty.kind == "fatek-serial" and pty.address.startswith("/dev/") and os.path.exists(pty.address)


def test_tcp_handle(tcp):
    assert tcp.kind == "fatek-tcp" and _tcp_address(tcp)[1] > 0


def test_read_registers_request_of_limit_size(client):
    # 64 words in one frame and 32 double words in one frame: the codec and server agree on the limits.
    client.write_words("R0", list(range(64)))
    assert client.request(ReadRegisters(parse("R0"), 64)) == list(range(64))
    assert len(client.request(ReadRegisters(parse("DR0"), 32))) == 32
