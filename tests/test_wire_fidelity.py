"""The emulator on the wire, checked with clients nobody here wrote (mbpoll where installed) and raw sockets:
where it used to differ from a real FBs or from the Modbus specification."""

from __future__ import annotations

import shutil
import socket
import struct
import subprocess

import pytest

from hil.families.fbs.protocol.fatek import build_frame, split_frame
from hil.families.fbs.sim import Emulator
from hil.families.fbs.sim.serve_fatek import start_fatek_tcp
from hil.families.fbs.sim.serve_modbus import start_modbus_tcp


@pytest.fixture
def emulator() -> Emulator:
    emu = Emulator()
    emu.memory.set("R4128", 1234)
    emu.memory.set("R1", 7)
    return emu


@pytest.fixture
def modbus(emulator: Emulator):
    handle = start_modbus_tcp(emulator)
    host, port = handle.address.rsplit(":", 1)
    yield host, int(port)
    handle.stop()


def adu(tid: int, unit: int, pdu: bytes) -> bytes:
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu


def exchange(address: tuple[str, int], data: bytes, replies: int = 1) -> list[bytes]:
    """Send ``data`` in one segment; collect ``replies`` MBAP frames (fewer on a timeout)."""
    out: list[bytes] = []
    buffer = b""
    with socket.create_connection(address, timeout=2) as s:
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        s.sendall(data)
        try:
            while len(out) < replies:
                chunk = s.recv(4096)
                if not chunk:
                    break
                buffer += chunk
                while len(buffer) >= 6 and len(buffer) >= 6 + int.from_bytes(buffer[4:6], "big"):
                    size = 6 + int.from_bytes(buffer[4:6], "big")
                    out.append(buffer[:size])
                    buffer = buffer[size:]
        except TimeoutError:
            pass
    return out


def pdu_of(frame: bytes) -> tuple[int, int, bytes]:
    """(transaction id, unit id, PDU) of one MBAP frame."""
    return int.from_bytes(frame[:2], "big"), frame[6], frame[7:]


# -- Modbus/TCP unit ids ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("unit", [1, 0, 0xFF])
def test_unit_ids_0_and_ff_are_this_plc_on_tcp(modbus, unit: int) -> None:
    (reply,) = exchange(modbus, adu(9, unit, bytes([3, 0x10, 0x20, 0, 1])))
    assert pdu_of(reply) == (9, unit, bytes([3, 2, 0x04, 0xD2]))  # R4128 = 1234, the unit id echoed


def test_another_unit_id_is_still_gateway_exception(modbus) -> None:
    (reply,) = exchange(modbus, adu(1, 7, bytes([3, 0x10, 0x20, 0, 1])))
    assert pdu_of(reply)[2] == bytes([0x83, 0x0B])


@pytest.mark.skipif(shutil.which("mbpoll") is None, reason="mbpoll is not installed (apt-get install mbpoll)")
@pytest.mark.parametrize("unit", ["255", "0", "1"])
def test_mbpoll_reads_with_unit_ids_0_ff_and_1(modbus, unit: str) -> None:
    host, port = modbus
    done = subprocess.run(["mbpoll", "-m", "tcp", "-a", unit, "-p", str(port), "-0", "-r", "4128", "-c", "1",
                           "-t", "4", "-1", "-o", "2", host], capture_output=True, text=True, timeout=20)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "[4128]: \t1234" in done.stdout


# -- several requests in one segment ------------------------------------------------------------------------------
def test_requests_in_one_segment_are_all_answered_in_order(modbus) -> None:
    batch = (adu(1, 1, bytes([3, 0, 1, 0, 1])) + adu(2, 1, bytes([3, 0x10, 0x20, 0, 1]))
             + adu(3, 1, bytes([1, 0, 0, 0, 0])) + adu(4, 0xFF, bytes([3, 0, 1, 0, 1])))
    replies = exchange(modbus, batch, replies=4)
    assert [pdu_of(r) for r in replies] == [(1, 1, bytes([3, 2, 0, 7])), (2, 1, bytes([3, 2, 0x04, 0xD2])),
                                            (3, 1, bytes([0x81, 3])), (4, 0xFF, bytes([3, 2, 0, 7]))]


def test_a_request_split_across_segments_is_still_one_request(modbus) -> None:
    frame = adu(5, 1, bytes([3, 0x10, 0x20, 0, 1]))
    with socket.create_connection(modbus, timeout=2) as s:
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        s.sendall(frame[:4])
        import time
        time.sleep(0.05)
        s.sendall(frame[4:] + frame)  # the rest, then a whole second copy
        data = b""
        while len(data) < 2 * 11:
            data += s.recv(4096)
    assert data == 2 * (frame[:4] + bytes([0, 5, 1, 3, 2, 0x04, 0xD2]))


# -- FC05 values and quantities -------------------------------------------------------------------------------------
def test_fc05_value_other_than_ff00_or_0000_is_exception_3(modbus, emulator: Emulator) -> None:
    (reply,) = exchange(modbus, adu(1, 1, bytes([5, 0, 0, 0x12, 0x34])))  # Y0 := 1234H
    assert pdu_of(reply)[2] == bytes([0x85, 3])
    assert emulator.memory.get("Y0") == 0
    (reply,) = exchange(modbus, adu(2, 1, bytes([5, 0, 0, 0xFF, 0x00])))
    assert pdu_of(reply)[2] == bytes([5, 0, 0, 0xFF, 0x00]) and emulator.memory.get("Y0") == 1
    (reply,) = exchange(modbus, adu(3, 1, bytes([5, 0, 0, 0x00, 0x01])))  # 0001H is not OFF either
    assert pdu_of(reply)[2] == bytes([0x85, 3]) and emulator.memory.get("Y0") == 1


@pytest.mark.parametrize("pdu, reply", [
    (bytes([1, 0, 0, 0, 0]), bytes([0x81, 3])),  # quantity 0
    (bytes([1, 0, 0, 0x07, 0xD1]), bytes([0x81, 3])),  # 2001 coils
    (bytes([3, 0, 0, 0, 0]), bytes([0x83, 3])),
    (bytes([3, 0, 0, 0, 126]), bytes([0x83, 3])),  # 126 registers
    (bytes([15, 0, 0, 0, 0, 0]), bytes([0x8F, 3])),
    (bytes([15, 0, 0, 0x07, 0xB1, 0xF7]) + bytes(0xF7), bytes([0x8F, 3])),  # 1969 coils
    (bytes([16, 0, 0, 0, 0, 0]), bytes([0x90, 3])),
    (bytes([2, 0, 0, 0, 0]), bytes([0x82, 1])),  # the FBs has no discrete inputs: the function comes first
    (bytes([4, 0, 0, 0, 0]), bytes([0x84, 1])),
    (bytes([0x41, 0, 0]), bytes([0xC1, 1])),  # a function nobody implements: its own code, exception 1
])
def test_bad_quantities_are_exception_3_of_their_own_function(modbus, pdu: bytes, reply: bytes) -> None:
    (answer,) = exchange(modbus, adu(1, 1, pdu))
    assert pdu_of(answer)[2] == reply


# -- FATEK ----------------------------------------------------------------------------------------------------------
@pytest.fixture
def fatek(emulator: Emulator):
    handle = start_fatek_tcp(emulator)
    host, port = handle.address.rsplit(":", 1)
    yield host, int(port)
    handle.stop()


def fatek_request(address: tuple[str, int], command: str, data: str) -> str:
    with socket.create_connection(address, timeout=2) as s:
        s.sendall(build_frame(1, command, data))
        reply = b""
        while not reply.endswith(b"\x03"):
            reply += s.recv(4096)
    return split_frame(reply).data


@pytest.mark.parametrize("command, data, error", [
    ("46", "01R04168", "A"), ("46", "01R04999", "A"), ("46", "02R04167", "A"), ("47", "01R045001234", "A"),
    ("48", "02R00000R04200", "A"),
    ("45", "01M00002", "2"), ("49", "01M00002", "2"), ("41", "7", "2"), ("42", "7M0000", "2"),
    ("45", "01M99992", "A"),  # two faults: the name comes first in the frame
    ("42", "9M9999", "2"),  # two faults: the action comes first
])
def test_fatek_errors_a_and_2(fatek, command: str, data: str, error: str, emulator: Emulator) -> None:
    before = emulator.memory.snapshot()
    assert fatek_request(fatek, command, data) == error
    assert emulator.memory.snapshot() == before


def test_fatek_registers_either_side_of_the_missing_block_are_served(fatek) -> None:
    assert fatek_request(fatek, "46", "01R04167").startswith("0")
    assert fatek_request(fatek, "46", "01R05000").startswith("0")
