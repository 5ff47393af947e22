"""The S7 emulator served over the S7 protocol (ISO-on-TCP), with python-snap7's pure-Python server.

The memory is the emulator's, not the server's: every read and write of V (DB 1), Q (PA) and I (PE) runs through
:meth:`hil.sim.engine.Engine.service`, so it is handled at a scan boundary like any other request, and a client
sees exactly what the Modbus view shows.  The protocol's clock functions read and set the emulator's CPU clock
(:class:`~hil.families.s7smart.sim.clock.S7Clock`), the same clock READ_RTC reads.

python-snap7's server keeps its memory in registered buffers and answers the clock from the host; the three
hooks overridden below (``_read_from_memory_area``, ``_write_to_memory_area``, the clock handlers) are its
internal dispatch points, pinned by the version range in pyproject.toml and covered by tests/test_s7_wire.py.
"""

from __future__ import annotations

import datetime as dt
import logging
import struct
from typing import Any

from hil.families.s7smart.address import AREA_BYTES
from hil.families.s7smart.protocol import timebuf
from hil.families.s7smart.protocol.s7 import V_DB, snap7_module
from hil.families.s7smart.sim.clock import S7Clock
from hil.families.s7smart.sim.cpu import S7Emulator
from hil.sim.runtime import ServerHandle

# S7 item return codes (the data section of a read/write reply)
_OK, _OUT_OF_RANGE, _NO_OBJECT = 0xFF, 0x05, 0x0A


def start_s7_server(emulator: S7Emulator, host: str = "127.0.0.1", port: int = 0) -> ServerHandle:
    """Serve ``emulator`` on ``host:port`` (0: the OS picks); the handle's ``address`` is ``host:port``."""
    snap7 = snap7_module()
    logging.getLogger("snap7").setLevel(logging.WARNING)  # its per-request INFO lines are not ours to print
    # … nor its server's per-request warning about the address fallback of a request this server answers itself
    # (one line every few requests: a long run fills the pipe of whoever reads `hil emulate`'s stderr, and blocks)
    logging.getLogger("snap7.server").setLevel(logging.ERROR)
    server = _server_class(snap7)(emulator)
    server.start_to(host, port)
    bound = server.server_socket.getsockname()[1]
    return ServerHandle("s7-tcp", f"{host}:{bound}", server.stop)


def _server_class(snap7: Any) -> type:
    Area = snap7.type.Area

    class EmulatorS7Server(snap7.server.Server):
        def __init__(self, emulator: S7Emulator) -> None:
            super().__init__(log=False)
            self.emulator = emulator

        def _area(self, area: Any, db_number: int) -> str | None:
            if area == Area.DB:
                return "V" if db_number == V_DB else None
            return {Area.PA: "Q", Area.PE: "I"}.get(area)

        def _read_from_memory_area(self, area: Any, db_number: int, start: int, count: int) -> tuple[int, bytearray]:
            name = self._area(area, db_number)
            if name is None:
                return _NO_OBJECT, bytearray()
            if start < 0 or count < 0 or start + count > AREA_BYTES[name]:
                return _OUT_OF_RANGE, bytearray()
            data = self.emulator.service(lambda mem: mem.read_bytes(name, start, count))
            return _OK, bytearray(data)

        def _write_to_memory_area(self, area: Any, db_number: int, start: int, data: bytearray) -> bool:
            name = self._area(area, db_number)
            if name is None or name == "I" or start < 0 or start + len(data) > AREA_BYTES[name]:
                return False  # the CPU's inputs are its own; nothing outside the area is written
            self.emulator.service(lambda mem: mem.write_bytes(name, start, bytes(data)))
            return True

        def _clock(self) -> S7Clock | None:
            return self.emulator.model(S7Clock)

        def _handle_get_clock(self, request: dict, userdata_params: dict, client_address: Any) -> bytes:
            clock = self._clock()
            if clock is None:
                return self._build_userdata_error_response(request, 0x8104)
            now = self.emulator.service(lambda mem: clock.time(self.emulator.now))
            return self._build_userdata_success_response(request, userdata_params, _clock_bytes(now))

        def _handle_set_clock(self, request: dict, userdata_params: dict, client_address: Any) -> bytes:
            clock = self._clock()
            raw = request.get("data", {}).get("data", b"")
            try:
                when = _clock_time(raw)
            except ValueError:
                return self._build_userdata_error_response(request, 0x8104)
            if clock is None:
                return self._build_userdata_error_response(request, 0x8104)
            self.emulator.service(lambda mem: clock.load(self.emulator.now, when))
            return self._build_userdata_success_response(request, userdata_params, b"", null_ack=True)

    return EmulatorS7Server


def _clock_bytes(when: dt.datetime) -> bytes:
    """The protocol's 10-byte clock: reserved, century/year BCD, month … second BCD, ms and weekday (1 = Sunday)."""
    bcd = timebuf.to_bcd
    return struct.pack(">10B", 0x00, 0x20 if when.year >= 2000 else 0x19, bcd(when.year % 100), bcd(when.month),
                       bcd(when.day), bcd(when.hour), bcd(when.minute), bcd(when.second), 0,
                       when.isoweekday() % 7 + 1)


def _clock_time(raw: bytes) -> dt.datetime:
    """The time in a set-clock request (10 bytes as :func:`_clock_bytes`; the year is bytes 2, 1990–2089)."""
    if len(raw) != 10:
        raise ValueError(f"a clock is 10 bytes, not {len(raw)}")
    digits = [d for d in (timebuf.from_bcd(b) for b in raw[2:8]) if d is not None]
    if len(digits) != 6:
        raise ValueError("not BCD")
    year, month, day, hour, minute, second = digits
    return dt.datetime(2000 + year if year < 90 else 1900 + year, month, day, hour, minute, second)
