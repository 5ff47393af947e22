"""ModbusTransport: an FBs reached over Modbus/TCP or Modbus RTU through the default map, with pymodbus's clients.

Every request is resolved through :mod:`hil.families.fbs.protocol.modbus_map` *before* anything is sent, so an element the
default map cannot reach (D4054, R4168…) raises :class:`~hil.core.errors.UnreachableAddress` instead of silently
reading some other register.  Requests of any shape become contiguous runs per table — coils via FC01/FC15,
holding registers via FC03/FC16 — split at the protocol limits (2000/1968 coils, 125/123 registers).
"""

from __future__ import annotations

import time
from typing import Callable, Iterable, Mapping, Sequence

from pymodbus import FramerType
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.pdu import ModbusPDU

from hil.families.fbs.address import Address, parse, span
from hil.io.modbus_codes import EXCEPTION_NAMES
from hil.core.errors import OutcomeUnknown, PlcErrorReply, ReplyTimeout, TransportError
from hil.families.fbs.protocol import modbus_map as mm
from hil.families.fbs.protocol.modbus_map import COIL, HOLDING, MAX_READ, MAX_WRITE, Run
from hil.families.fbs.transport.base import Limits, NameLike, PlcStatus, Transport, check_value
from hil.io.serial_line import line_coding

_FC_NAMES = {1: "FC01 read coils", 3: "FC03 read holding registers", 15: "FC15 write coils",
             16: "FC16 write holding registers"}
#: A cheap read that proves the PLC answers: R4128 (RTC seconds), always mapped.
PROBE = Run(HOLDING, 4128, 1)
PROBE_SPAN = 8  # R4128–R4135 are mapped: a resynchronising read picks its quantity in 1–8


class _Shape(Exception):
    """A reply that does not answer the request sent (wrong function, unit or quantity)."""


class ModbusTransport(Transport):
    """An FBs over Modbus (default map).  Build with :meth:`tcp` or :meth:`rtu`; use as a context manager."""

    # The base class splits read_* and write_* at one size; these are the read limits (FC01/FC03).  Runs are split
    # again at the (smaller) write limits, and Modbus requests are counted one by one in ``requests``.
    limits = Limits(words=MAX_READ[HOLDING], bits=MAX_READ[COIL], mixed_read_words=MAX_READ[HOLDING],
                    mixed_write_words=MAX_WRITE[HOLDING])

    def __init__(self, client: ModbusTcpClient | ModbusSerialClient, description: str, *, unit: int,
                 timeout: float, retries: int, hint: str, backoff: float = 0.05) -> None:
        super().__init__(description)
        self.client = client  # built with retries=0: pymodbus would repeat writes too; we retry reads only
        self.unit = unit
        self.timeout = timeout
        self.retries = retries
        self.backoff = backoff
        self._hint = hint
        self.serial = isinstance(client, ModbusSerialClient)
        self.dirty = False  # True: a late reply may be on the line; recover before the next request
        self._abandoned: set[tuple[int, int]] = set()  # (fc, quantity) of requests given up since the last sync
        self._sync_count = 0
        self._inflight: tuple[int, int] | None = None
        self.resyncs = 0
        self.reconnects = 0
        if not client.connect():
            client.close()
            raise TransportError(f"cannot connect to {description}: {hint}")

    # -- constructors -----------------------------------------------------------------------------------------
    @classmethod
    def tcp(cls, host: str, port: int = 502, *, unit: int = 1, timeout: float = 1.0,
            retries: int = 2) -> "ModbusTransport":
        """Modbus/TCP to ``host:port`` (an FBs Ethernet module serves port 502, at most 8 clients)."""
        client = ModbusTcpClient(host, port=port, timeout=timeout, retries=0)
        hint = (f"is the PLC powered and reachable at {host}:{port} (ping it), does its Ethernet module serve "
                f"Modbus/TCP on that port, and are fewer than 8 clients connected?")
        return cls(client, f"modbus+tcp://{host}:{port}?unit={unit}", unit=unit, timeout=timeout,
                   retries=retries, hint=hint)

    @classmethod
    def rtu(cls, device: str, *, baudrate: int = 9600, parity: str = "E", bytesize: int = 8, stopbits: int = 1,
            unit: int = 1, timeout: float = 1.0, retries: int = 2) -> "ModbusTransport":
        """Modbus RTU on serial ``device`` (a path such as /dev/ttyUSB0 or a pty, or a pyserial URL)."""
        bytesize, parity, stopbits = line_coding(device, bytesize, parity, stopbits)
        client = ModbusSerialClient(device, framer=FramerType.RTU, baudrate=baudrate, bytesize=bytesize,
                                    parity=parity, stopbits=stopbits, timeout=timeout, retries=0)
        hint = (f"does {device} exist, and is no other program holding it open? The PLC port must be in Modbus "
                f"RTU slave mode (R4047, e.g. 5502H for port 1; port 0 never speaks Modbus)")
        return cls(client, f"modbus+rtu://{device}?baudrate={baudrate}&parity={parity}&unit={unit}", unit=unit,
                   timeout=timeout, retries=retries, hint=hint)

    # -- validation before anything is sent --------------------------------------------------------------------
    def unreachable_reason(self, address: NameLike) -> str | None:
        return mm.unreachable_reason(address)

    def read_words(self, address: NameLike, count: int = 1) -> list[int]:
        self._check_run(address, count)
        return super().read_words(address, count)

    def write_words(self, address: NameLike, values: Sequence[int]) -> None:
        # Not the base class's chunking: it splits writes at the read limit (125), and 123 + 2 + … would cost
        # an extra request per chunk; _write_items splits at the FC16/FC15 limits itself.
        self._write_run_of(self._word_address(address), values)

    def read_bits(self, address: NameLike, count: int = 1) -> list[int]:
        self._check_run(address, count)
        return super().read_bits(address, count)

    def write_bits(self, address: NameLike, values: Sequence[int | bool]) -> None:
        self._write_run_of(self._bit_address(address), values)

    def _write_run_of(self, first: Address, values: Sequence[int | bool]) -> None:
        items = [(a, check_value(a, int(v))) for a, v in zip(span(first, len(values)), values)]
        with self._lock:
            self._write_items(items)  # resolves every address before the first request

    def read_many(self, names: Iterable[NameLike]) -> list[int]:
        names = list(names)
        for name in names:
            mm.to_modbus(name)
        return super().read_many(names)

    def write_many(self, items: Mapping[NameLike, int] | Iterable[tuple[NameLike, int]]) -> None:
        pairs = list(items.items()) if isinstance(items, Mapping) else list(items)
        for name, _ in pairs:
            mm.to_modbus(name)
        super().write_many(pairs)

    @staticmethod
    def _check_run(address: NameLike, count: int) -> None:
        """The base class sends large requests in pieces; refuse the whole request before the first piece."""
        if count >= 1:
            for a in span(parse(address), count):
                mm.to_modbus(a)

    # -- primitives ---------------------------------------------------------------------------------------------
    def _read_words(self, first: Address, count: int) -> list[int]:
        return self._read_addresses(span(first, count))

    def _write_words(self, first: Address, values: list[int]) -> None:
        self._write_items(list(zip(span(first, len(values)), values)))

    _read_bits = _read_words
    _write_bits = _write_words

    def _read_many(self, addresses: list[Address]) -> list[int]:
        return self._read_addresses(addresses)

    def _write_many(self, items: list[tuple[Address, int]]) -> None:
        self._write_items(items)

    def _status(self) -> PlcStatus:
        """Modbus has no status command: RUN/STOP is unknown here (a FATEK target can tell).

        A real read of R4128 (holding 4128, always mapped) proves that the PLC answers, so a status that
        returns means the wire and the unit work.
        """
        (seconds,) = self._read_run(PROBE)
        return PlcStatus(running=None, via="modbus",
                         identity={"transport": self.description, "unit": str(self.unit),
                                   "probe": f"R4128 = {seconds}"})

    def _close(self) -> None:
        self.client.close()

    def _count(self, result):  # noqa: ANN001, ANN202 - requests are counted per Modbus frame in _exchange
        return result

    # -- runs -------------------------------------------------------------------------------------------------
    def _read_addresses(self, addresses: Sequence[Address]) -> list[int]:
        runs = mm.coalesce(addresses, limits=MAX_READ)  # raises UnreachableAddress before any I/O
        values: dict[mm.Unit, int] = {}
        for run in runs:
            for i, value in enumerate(self._read_run(run)):
                values[(run.table, run.pdu + i)] = value
        return [mm.decode(a, values) for a in addresses]

    def _write_items(self, items: Sequence[tuple[Address, int]]) -> None:
        checked = [(a, check_value(a, v)) for a, v in items]
        for run, values in mm.coalesce_writes(checked, limits=MAX_WRITE):  # all resolved before any I/O
            self._write_run(run, values)

    def _read_run(self, run: Run) -> list[int]:
        if run.table == COIL:
            rr = self._exchange(1, run, lambda: self.client.read_coils(run.pdu, count=run.count,
                                                                       device_id=self.unit))
            if len(rr.bits) != (run.count + 7) // 8 * 8:
                raise _Shape(f"{len(rr.bits)} coil bits for {run.count} asked")
            return [1 if b else 0 for b in rr.bits[:run.count]]  # bits come padded to a multiple of 8
        rr = self._exchange(3, run, lambda: self.client.read_holding_registers(run.pdu, count=run.count,
                                                                               device_id=self.unit))
        return list(rr.registers)

    def _write_run(self, run: Run, values: list[int]) -> None:
        if run.table == COIL:
            self._exchange(15, run, lambda: self.client.write_coils(run.pdu, [bool(v) for v in values],
                                                                    device_id=self.unit))
        else:
            self._exchange(16, run, lambda: self.client.write_registers(run.pdu, values, device_id=self.unit))

    def budget(self, write: bool = False) -> float:
        """The longest one Modbus request can take, retries, backoff and recovery included."""
        tries = 1 + self.retries
        recover = tries * self.timeout + sum(self._backoff(a) for a in range(1, tries)) + 0.5
        if write:
            return recover + self.timeout
        return tries * (recover + self.timeout) + sum(self._backoff(a) for a in range(1, tries))

    def _backoff(self, attempt: int) -> float:
        return self.backoff * min(2 ** (attempt - 1), 8)

    def reopen(self) -> None:
        """Close and reconnect the client (a new TCP connection, the serial port opened again)."""
        with self._lock:
            self.client.close()
            if not self.client.connect():
                raise TransportError(f"cannot reconnect to {self.description}: {self._hint}")
            self.reconnects += 1
            self.dirty = self.serial  # a late reply may still come on a serial line

    def _recover(self, what: str) -> None:
        """After a fault: on TCP a new connection (transaction ids guard the rest, but a stream with junk in
        it never re-frames); on RTU, which has no transaction id, a read whose reply has a quantity no
        abandoned request had — every reply before it is stale, and the line is in step again."""
        if not self.serial:
            try:
                self.reopen()
            except TransportError as exc:
                raise TransportError(f"{what} not sent: {exc}") from None
            self.dirty = False
            return
        tries = 1 + self.retries
        last = ""
        for attempt in range(1, tries + 1):
            used = {count for fc, count in self._abandoned | ({self._inflight} if self._inflight else set())
                    if fc == 3}
            choices = [c for c in range(1, PROBE_SPAN + 1) if c not in used] or [1]
            self._sync_count += 1
            count = choices[self._sync_count % len(choices)]
            self._flush()
            try:
                rr = self.client.read_holding_registers(PROBE.pdu, count=count, device_id=self.unit)
            except ModbusException as exc:
                rr, last = None, f"no reply ({exc})"
            if rr is not None:
                if (not rr.isError() and rr.function_code == 3 and rr.dev_id == self.unit
                        and len(rr.registers) == count):
                    self.dirty = False
                    self._abandoned.clear()
                    self.resyncs += 1
                    return
                last = f"a stale reply (function {rr.function_code}) came first"
            self._abandoned.add((3, count))
            if attempt < tries:
                time.sleep(self._backoff(attempt))
        raise ReplyTimeout(f"{what} not sent to {self.description}: the line could not be resynchronised after "
                           f"an earlier fault ({last})")

    def _flush(self) -> None:
        """Drop whatever is waiting on a serial line (a late reply) before a request."""
        port = getattr(self.client, "socket", None)
        if self.serial and port is not None:
            try:
                port.reset_input_buffer()
            except (OSError, ValueError, AttributeError):
                pass

    def _exchange(self, fc: int, run: Run, send: Callable[[], ModbusPDU]) -> ModbusPDU:
        """One Modbus request; reads are retried with backoff, writes never are.  Every failure becomes a harness
        error naming the request, the target and the fault seen."""
        what = f"{_FC_NAMES[fc]} at {run.pdu} ×{run.count} ({self._names(run)})"
        write = fc in (15, 16)
        attempts = 1 if write else 1 + self.retries
        started = time.monotonic()
        faults: list[str] = []
        for attempt in range(1, attempts + 1):
            try:
                if self.dirty:
                    self._recover(what)  # raises before anything is sent
                self._flush()
                self.requests += 1
                # Suspect until the reply is in: an exchange cut short (pytest-timeout's signal, Ctrl-C)
                # leaves its reply on the way.
                self.dirty, self._inflight = True, (fc, run.count)
                rr = self._check(fc, run, send())
                self.dirty, self._inflight = False, None
                return rr
            except PlcErrorReply:
                self.dirty, self._inflight = False, None  # an exception reply is still our reply
                raise
            except ReplyTimeout as exc:  # the recovery failed: nothing was sent
                if write:
                    raise
                faults.append(str(exc))
                if attempt == attempts:
                    raise ReplyTimeout(f"{faults[0]}; then {exc}; {attempts} tries of {self.timeout:g} s "
                                       f"({attempts * self.timeout:g} s), {time.monotonic() - started:.2f} s "
                                       f"in all") from None
            except (ModbusException, _Shape) as exc:
                self.dirty = True
                self._abandoned.add((fc, run.count))
                fault = self._fault(exc, what, attempt, attempts)
                if write:
                    raise OutcomeUnknown(f"{fault}; outcome unknown: the write may or may not have been applied "
                                         f"(writes are not retried)") from None
                faults.append(fault)
                if attempt == attempts:
                    if attempts > 1:
                        fault += (f"; {attempts} tries of {self.timeout:g} s ({attempts * self.timeout:g} s), "
                                  f"{time.monotonic() - started:.2f} s in all")
                    raise (ReplyTimeout if isinstance(exc, ModbusIOException) else TransportError)(fault) from None
            time.sleep(self._backoff(attempt))
        raise AssertionError("unreachable")

    def _fault(self, exc: Exception, what: str, attempt: int, attempts: int) -> str:
        where = f"{what} on {self.description} (attempt {attempt} of {attempts})"
        if isinstance(exc, _Shape):
            return f"a reply of the wrong shape to {where}: {exc}"
        if isinstance(exc, ModbusIOException):
            return (f"no valid reply to {where} within {self.timeout:g} s: check the unit id, wiring/serial "
                    f"settings and that the PLC is powered [pymodbus: {exc}]")
        if isinstance(exc, ConnectionException):
            return f"lost the connection during {where}: {self._hint} [pymodbus: {exc}]"
        return f"{where} failed: {exc}"

    def _check(self, fc: int, run: Run, rr: ModbusPDU) -> ModbusPDU:
        """The reply must answer exactly this request: our unit, our function, our quantity (and address)."""
        if rr.isError():
            if getattr(rr, "function_code", 0) & 0x7F != fc:
                raise _Shape(f"an exception reply to function {rr.function_code & 0x7F}")
            code = getattr(rr, "exception_code", None)
            meaning = EXCEPTION_NAMES.get(code, "unknown Modbus exception") if code is not None else "error reply"
            raise PlcErrorReply(str(code), meaning, f"{_FC_NAMES[fc]} at {run.pdu} ×{run.count} "
                                f"({self._names(run)}) on {self.description}")
        if rr.function_code != fc:
            raise _Shape(f"function {rr.function_code} answered function {fc}")
        if rr.dev_id not in (0, self.unit):
            raise _Shape(f"unit {rr.dev_id} answered, expected {self.unit}")
        if fc == 3 and len(rr.registers) != run.count:
            raise _Shape(f"{len(rr.registers)} registers for {run.count} asked")
        if fc in (15, 16) and (rr.address != run.pdu or rr.count != run.count):
            raise _Shape(f"the write echo names {rr.count} at {rr.address}, sent {run.count} at {run.pdu}")
        return rr

    @staticmethod
    def _names(run: Run) -> str:
        """The FBs elements at the ends of a run, for error messages."""
        first = mm.locate(run.table, run.pdu)
        last = mm.locate(run.table, run.end - 1)
        a = str(first[0]) if first else "unmapped"
        b = str(last[0]) if last else "unmapped"
        return a if run.count == 1 or a == b else f"{a}–{b}"


__all__ = ["ModbusTransport", "EXCEPTION_NAMES"]
