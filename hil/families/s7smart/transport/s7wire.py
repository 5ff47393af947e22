"""An S7-200 SMART over its own protocol (S7 communication on ISO-on-TCP, port 102), with python-snap7's client.

S7 clients address V memory as DB 1, the outputs Q as the process-output area (PA) and the inputs I as the
process-input area (PE).  The CPU's own clock is reached with the protocol's clock functions (``cpu_clock`` /
``set_cpu_clock``), beside the READ_RTC / SET_RTC test program the suites drive.

The rules are the harness's everywhere: reads are retried (after a reconnect) up to ``retries`` times; a write
whose reply never came is OutcomeUnknown and is never sent again; every failure names the request, the target
and the S7 error.  python-snap7 is an optional extra (``pip install 'hil[s7]'``).
"""

from __future__ import annotations

import contextlib
import datetime as dt
from collections.abc import Callable
from typing import Any, TypeVar

from hil.core.errors import HilError, TransportError
from hil.families.s7smart.address import AREA_BYTES, S7Address, parse_s7
from hil.families.s7smart.protocol.s7 import DEFAULT_PORT, V_DB, snap7_module
from hil.families.s7smart.transport.io import S7Io
from hil.io.request_policy import RequestPolicy
from hil.io.status import PlcStatus

T = TypeVar("T")


class _Lost(Exception):
    """A request whose reply never came (a timeout, a broken connection): the policy's to retry or report."""


class SnapS7Io(S7Io):
    """``s7+tcp://HOST:102?rack=0&slot=1``: V bytes, Q/I bits and the CPU clock over the S7 protocol."""

    def __init__(self, host: str, port: int = DEFAULT_PORT, *, rack: int = 0, slot: int = 1, timeout: float = 1.0,
                 retries: int = 2, description: str | None = None) -> None:
        super().__init__(description or f"s7+tcp://{host}:{port}?rack={rack}&slot={slot}")
        self._snap7 = snap7_module()
        self.host, self.port, self.rack, self.slot = host, port, rack, slot
        self.timeout = timeout
        self.retries = retries
        self.policy = RequestPolicy(retries)
        self.reconnects = 0
        self.client = self._snap7.client.Client()
        self._connect()

    # -- the connection ---------------------------------------------------------------------------------------
    def _connect(self) -> None:
        try:
            self.client.connect(self.host, self.rack, self.slot, self.port)
        except self._snap7.error.S7Error as exc:
            raise TransportError(f"cannot connect to {self.description}: {exc} — is the CPU reachable on port "
                                 f"{self.port}, and are rack {self.rack} / slot {self.slot} right (an S7-200 SMART "
                                 f"takes rack 0, slot 1)?") from None
        connection = self.client.connection  # python-snap7 keeps its ISO-on-TCP connection here
        connection.timeout = self.timeout
        if getattr(connection, "socket", None) is not None:
            connection.socket.settimeout(self.timeout)

    def reopen(self) -> None:
        with self._lock:
            self.client.disconnect()
            self._connect()
            self.reconnects += 1

    def _close(self) -> None:
        self.client.disconnect()

    def _call(self, what: str, send: Callable[[], T], *, write: bool = False) -> T:
        """One S7 request under the harness's request policy (:mod:`hil.io.request_policy`): snap7 supplies the
        try, a timeout or a broken connection is a lost request (reads: a fresh connection, then again), an S7
        error from the CPU is a refusal."""
        error = self._snap7.error

        def attempt(_n: int, _tries: int) -> T:
            if not self.client.get_connected():
                self.reopen()
            self.requests += 1
            try:
                return send()
            except error.S7TimeoutError as exc:
                raise _Lost(f"no reply within {self.timeout:g} s [S7: {exc}]") from None
            except error.S7ConnectionError as exc:
                raise _Lost(f"connection failed [S7: {exc}]") from None
            except error.S7Error as exc:  # the CPU answered with an error: the request was refused, not lost
                raise TransportError(f"{what} on {self.description} refused: {exc}") from None
            except OSError as exc:
                raise _Lost(str(exc)) from None

        def recover() -> None:
            with contextlib.suppress(Exception):  # already broken: whatever disconnecting it raises
                self.client.disconnect()
        return self.policy.run(f"{what} on {self.description}", attempt, write=write, lost=(_Lost,), recover=recover,
                               one_try=self.timeout)

    def budget(self, write: bool = False) -> float:
        """The longest one S7 request can take, retries, backoff and reconnecting included (a try: the request and
        a reconnect, each within the timeout)."""
        return self.policy.budget(2 * self.timeout, write)

    # -- primitives -------------------------------------------------------------------------------------------
    def _read_v(self, first: int, count: int) -> bytes:
        self._check_v(first, count)
        return bytes(self._call(f"read VB{first} ×{count} (DB{V_DB})", lambda: self.client.db_read(V_DB, first,
                                                                                                     count)))

    def _write_v(self, first: int, data: bytes) -> None:
        self._check_v(first, len(data))
        self._call(f"write VB{first} ×{len(data)} (DB{V_DB})",
                   lambda: self.client.db_write(V_DB, first, bytearray(data)), write=True)

    def _read_bits(self, area: str, first: int, count: int) -> list[int]:
        lo, hi = first // 8, (first + count - 1) // 8
        data = self._call(f"read {area}{lo}.0–{area}{hi}.7", lambda: self.client.read_area(
            self._area(area), 0, lo, hi - lo + 1))
        return [data[n // 8 - lo] >> n % 8 & 1 for n in range(first, first + count)]

    def _write_bits(self, area: str, first: int, values: list[int]) -> None:
        if area != "Q":
            raise HilError(f"{area} bits are the CPU's inputs: only Q bits are writable")
        lo, hi = first // 8, (first + len(values) - 1) // 8
        # S7 writes bytes: read the bytes, change the bits, write them back (the other bits are ours to keep)
        data = bytearray(self._call(f"read Q{lo}.0–Q{hi}.7", lambda: self.client.read_area(
            self._area("Q"), 0, lo, hi - lo + 1)))
        for n, value in enumerate(values, first):
            mask = 1 << n % 8
            data[n // 8 - lo] = data[n // 8 - lo] | mask if value else data[n // 8 - lo] & ~mask
        self._call(f"write Q{lo}.0–Q{hi}.7", lambda: self.client.write_area(self._area("Q"), 0, lo, data),
                   write=True)

    def _status(self) -> PlcStatus:
        state = self._call("read the CPU state", self.client.get_cpu_state)
        running = {"S7CpuStatusRun": True, "S7CpuStatusStop": False}.get(str(state))
        return PlcStatus(running=running, flags=["RUN"] if running else [], via="s7",
                         identity={"transport": self.description, "cpu state": str(state)})

    def unreachable_reason(self, name: str | S7Address) -> str | None:
        a = parse_s7(name)
        if a.area not in ("V", "Q", "I"):
            return f"{a} is not reached over this wire (V memory as DB{V_DB}, Q and I bits)"
        return None

    def plc_identity(self) -> dict[str, str] | None:
        """Which CPU this is (the S7 module identification: module type and serial number), for the journal and
        recovery; None when the CPU does not say."""
        try:
            info = self._call("read the CPU identity", self.client.get_cpu_info)
        except HilError:
            return None

        def text(value: object) -> str:
            return (value.decode("ascii", "replace") if isinstance(value, bytes) else str(value)).strip("\x00 ")
        return {"module": text(info.ModuleTypeName), "serial": text(info.SerialNumber)}

    # -- the CPU's own clock ----------------------------------------------------------------------------------
    def cpu_clock(self) -> dt.datetime:
        """The time-of-day clock, read with the S7 protocol's clock function."""
        with self._lock:
            return self._call("read the CPU clock", self.client.get_plc_datetime)

    def set_cpu_clock(self, when: dt.datetime) -> None:
        """Set the time-of-day clock with the S7 protocol's clock function."""
        with self._lock:
            self._call(f"set the CPU clock to {when:%Y-%m-%d %H:%M:%S}", lambda: self.client.set_plc_datetime(when),
                       write=True)

    # -- helpers ------------------------------------------------------------------------------------------------
    def _area(self, area: str) -> Any:
        return {"Q": self._snap7.type.Area.PA, "I": self._snap7.type.Area.PE}[area]

    @staticmethod
    def _check_v(first: int, count: int) -> None:
        if first < 0 or first + count > AREA_BYTES["V"]:
            raise HilError(f"VB{first}…VB{first + count - 1} is outside V memory (VB0–VB{AREA_BYTES['V'] - 1})")
