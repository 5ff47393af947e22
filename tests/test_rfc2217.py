"""Serial lines through an RFC 2217 server: ``fatek+rfc2217://`` and ``modbus+rfc2217://`` against the emulator's
pty exported by ser2net (what labgrid exporters run) and by pyserial's own port manager.

A relay between client and server (tests.rfc2217_servers.TelnetTap) records every RFC 2217 command either way: the
line settings go to the server once, at open, and the server acknowledges them; a request never costs a purge or a
renegotiation (pyserial's client makes one of each per ``reset_input_buffer()`` / ``.timeout`` change, ≈ 50 ms /
≈ 160 ms).
"""

from __future__ import annotations

import contextlib
import socket
import struct
import threading

import pytest

from hil.core.errors import TransportError
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.transport.factory import open_transport, serve
from tests.rfc2217_servers import (
    NO_SER2NET,
    SER2NET,
    SET_BAUDRATE,
    SET_DATASIZE,
    SET_PARITY,
    SET_STOPSIZE,
    TelnetTap,
    free_port,
    port_manager,
    ser2net,
)

SERVERS = [pytest.param("ser2net", marks=pytest.mark.skipif(SER2NET is None, reason=NO_SER2NET)), "pyserial"]
PARITY_EVEN = 3  # RFC 2217's code for E
#: (wire, URL scheme, query, the line settings the server must be asked for: baud, data bits, parity, stop bits)
WIRES = {
    "fatek": ("fatek-serial", "fatek+rfc2217", "station=1", (9600, 7, PARITY_EVEN, 1)),  # port 0's factory 7E1
    "modbus": ("modbus-rtu", "modbus+rfc2217", "unit=1&baudrate=115200&parity=E", (115200, 8, PARITY_EVEN, 1)),
}


@contextlib.contextmanager
def exported(server: str, device: str, line: str = "9600n81"):
    """``device`` behind ``server`` — started 8N1, so that 7E1 can only come from the client."""
    with (ser2net(device, line) if server == "ser2net" else port_manager(device)) as where:
        yield where


@contextlib.contextmanager
def served(wire: str):
    emulator = Emulator()
    handle = serve(emulator, wire)
    try:
        yield emulator, handle.address
    finally:
        handle.stop()


def _settings(commands: list[tuple[int, bytes]], offset: int = 0) -> dict[int, int]:
    """The last value of each line setting among ``commands`` (server answers carry the command + 100)."""
    out = {}
    for command, value in commands:
        key = command - offset
        if key == SET_BAUDRATE and len(value) == 4:
            out[key] = struct.unpack("!I", value)[0]
        elif key in (SET_DATASIZE, SET_PARITY, SET_STOPSIZE) and value:
            out[key] = value[0]
    return out


@pytest.mark.parametrize("server", SERVERS)
@pytest.mark.parametrize("protocol", WIRES)
def test_line_settings_go_once_and_requests_cost_no_purge(server, protocol):
    wire, scheme, query, expected = WIRES[protocol]
    with served(wire) as (emulator, device), exported(server, device) as where:
        tap = TelnetTap(where.rfc2217)
        try:
            transport = open_transport(f"{scheme}://{tap.address}?{query}&timeout=1")
            try:
                at_open = len(tap.records)
                keys = (SET_BAUDRATE, SET_DATASIZE, SET_PARITY, SET_STOPSIZE)
                asked = _settings(tap.commands("c"))
                answered = _settings(tap.commands("s"), offset=100)
                assert tuple(asked.get(k) for k in keys) == expected, tap.records
                assert tuple(answered.get(k) for k in keys) == expected, f"{server} answered {tap.records}"
                for n in range(30):
                    transport.write_words("R100", [n, n + 1])
                    assert transport.read_words("R100", 2) == [n, n + 1]
                    transport.write_bits("M10", [n % 2])
                    assert transport.read_bits("M10", 1) == [n % 2]
                assert emulator.memory.read("R100", 2) == [29, 30]  # the writes reached the PLC itself
                after = tap.commands("c", after=at_open)
                assert after == [], f"{len(after)} RFC 2217 commands in 120 requests: {after[:5]}"
            finally:
                transport.close()
        finally:
            tap.close()


@pytest.mark.timeout(20)
@pytest.mark.parametrize("scheme", ["fatek+rfc2217", "modbus+rfc2217"])
def test_a_port_nobody_listens_on_is_a_clear_error(scheme):
    port = free_port()  # a port the OS chose, closed again: nothing listens there
    with pytest.raises(TransportError, match=rf"rfc2217://127\.0\.0\.1:{port}.*nothing accepted the connection — "
                                             r"is the RFC 2217 server \(ser2net"):
        open_transport(f"{scheme}://127.0.0.1:{port}?timeout=0.5")


@pytest.mark.timeout(20)
def test_a_port_that_is_no_rfc2217_server_is_a_clear_error():
    """ser2net's raw accepter (or any TCP server) instead of its telnet(rfc2217) one: refused within the timeout."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    accepted: list[socket.socket] = []
    thread = threading.Thread(target=lambda: accepted.append(listener.accept()[0]), daemon=True)
    thread.start()
    try:
        with pytest.raises(TransportError, match="answered .*but not as an RFC 2217 server"):
            open_transport(f"fatek+rfc2217://127.0.0.1:{listener.getsockname()[1]}?timeout=0.5")
    finally:
        thread.join(5)
        for conn in accepted:
            conn.close()
        listener.close()


@pytest.mark.timeout(30)
@pytest.mark.parametrize("server", SERVERS)
@pytest.mark.parametrize("protocol", WIRES)
def test_a_server_that_goes_away_is_a_clear_error(server, protocol):
    wire, scheme, query, _ = WIRES[protocol]
    with served(wire) as (_, device):
        with exported(server, device) as where:
            transport = open_transport(f"{scheme}://{where.rfc2217}?{query}&timeout=0.5&retries=1")
            assert transport.read_words("R4128", 1)
        try:
            with pytest.raises(TransportError) as info:
                transport.read_words("R4128", 1)
            message = str(info.value)  # the retry found the server gone: it says so, naming it
            assert f"cannot open rfc2217://{where.rfc2217}: " in message, message
            assert "nothing accepted the connection — is the RFC 2217 server" in message, message
        finally:
            transport.close()


@pytest.mark.timeout(30)
@pytest.mark.skipif(SER2NET is None, reason=NO_SER2NET)
def test_a_port_another_client_holds_is_a_clear_error():
    """ser2net serves one connection per port and closes a second one at once ("Port already in use")."""
    with served("fatek-serial") as (_, device), exported("ser2net", device) as where:
        first = open_transport(f"fatek+rfc2217://{where.rfc2217}?timeout=0.5")
        try:
            with pytest.raises(TransportError,
                               match="the server closed the connection at once.* — another client holds the port"):
                open_transport(f"fatek+rfc2217://{where.rfc2217}?timeout=0.5")
            assert first.read_words("R4128", 1)  # the first client is undisturbed
        finally:
            first.close()
        second = open_transport(f"fatek+rfc2217://{where.rfc2217}?timeout=3")  # free again, once ser2net lets go
        second.close()
