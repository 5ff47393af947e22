"""The S7 link follows the harness's retry policy: reads retried by us, a write whose reply is lost is sent once
and reported as "outcome unknown" (pymodbus itself would repeat it)."""

from __future__ import annotations

import socket
import threading

import pytest

from hil.core.errors import OutcomeUnknown, ReplyTimeout
from hil.families.s7smart.transport.io import ModbusS7Io


class SilentServer:
    """Accepts a TCP connection and counts the Modbus requests it receives, answering none."""

    def __init__(self) -> None:
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.requests = 0
        self._stop = threading.Event()
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        self.sock.settimeout(0.05)
        conns = []
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
                conn.settimeout(0.02)
                conns.append(conn)
            except OSError:
                pass
            for conn in conns:
                try:
                    data = conn.recv(4096)
                except OSError:
                    continue
                # Each Modbus TCP request is 12+ bytes starting with a 7-byte MBAP header; count frames by header.
                while len(data) >= 7:
                    length = int.from_bytes(data[4:6], "big")
                    self.requests += 1
                    data = data[6 + length:]

    def close(self) -> None:
        self._stop.set()
        self.sock.close()


@pytest.fixture
def silent():
    server = SilentServer()
    yield server
    server.close()


def test_read_is_tried_retries_plus_one_times(silent):
    with (
        ModbusS7Io.tcp("127.0.0.1", silent.port, timeout=0.15, retries=2) as link,
        pytest.raises(ReplyTimeout, match="3 tries of 0.15 s"),
    ):
        link.read_v(0, 2)
    assert silent.requests == 3


def test_write_without_reply_is_sent_once_and_outcome_unknown(silent):
    with (
        ModbusS7Io.tcp("127.0.0.1", silent.port, timeout=0.15, retries=2) as link,
        pytest.raises(OutcomeUnknown, match="outcome unknown.*not retried"),
    ):
        link.write_v(0, b"\x00\x01")
    assert silent.requests == 1
