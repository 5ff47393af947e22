"""The one Modbus client: every family's Modbus wire goes through it, whatever its address map.

It owns the rules a Modbus request lives by, in one place:

* requests live by the one request policy (:mod:`hil.io.request_policy`) — pymodbus's own retries are off, since
  they would repeat writes too: reads are retried with its backoff, a write whose reply never came raises
  OutcomeUnknown and is never sent again;
* every reply must answer exactly the request sent (function, unit, quantity, write echo), else it is a fault;
* a late or repeated reply to an earlier request is never taken for the answer (docs/safety.md).  On TCP the
  transaction id tells: pymodbus skips a frame with another non-zero id and keeps waiting for ours, and refuses
  one with id 0 (tests/test_late_replies.py pins both).  RTU has no id: pymodbus drains the input before each
  request (the silent interval), and a read's reply must be the only thing received with nothing waiting after
  it, else the read is repeated.  On a line that may repeat a reply (``fence="reads"``: a gateway, a wire-fault
  plan) every read is also *fenced*: a probe read of a quantity the read did not have must be answered next
  (:meth:`ModbusWire._fence`); a direct line cannot repeat one, and a late one follows a timeout, after which the
  wire is resynchronised anyway (below);
* after a fault the wire is resynchronised before the next request: on TCP a new connection; on RTU, which has
  no transaction id, a probe read whose quantity no abandoned request had (every reply before it is stale);
* every failure becomes a harness error naming the request (with the family's names for it), the target and
  the fault seen.

A family's transport maps its element names to (table, address, count) runs with its address map and calls
:meth:`ModbusWire.read` / :meth:`ModbusWire.write`.  Frames reach ``observers`` (wire traces, statistics) through
pymodbus's public ``trace_packet`` hook, and requests and replies the fence through ``trace_pdu``, both given to
the client when it is built.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import serial
from pymodbus import FramerType
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.pdu import ModbusPDU

from hil.core.errors import InvalidValue, PlcErrorReply, TransportError
from hil.io.hosts import unresolved
from hil.io.line import Line, LocalLine, line_check, open_line
from hil.io.modbus_codes import EXCEPTION_NAMES, GATEWAY
from hil.io.request_policy import RequestPolicy, Resync
from hil.io.url import serial_target

COILS, DISCRETE_INPUTS, HOLDING = "coil", "discrete", "holding"
READ_FC = {COILS: 1, DISCRETE_INPUTS: 2, HOLDING: 3}
WRITE_FC = {COILS: 15, HOLDING: 16}
FC_NAMES = {1: "FC01 read coils", 2: "FC02 read discrete inputs", 3: "FC03 read holding registers",
            15: "FC15 write coils", 16: "FC16 write holding registers"}

Observer = Callable[[str, bytes], None]  # ("tx" | "rx", the frame's bytes)
#: the family's names for a run, for error messages: (table, first address, count) → "R100–R103"
Describe = Callable[[str, int, int], str]


@dataclass(frozen=True)
class Probe:
    """A cheap read that proves the PLC answers and resynchronises an RTU line: holding registers from
    ``address``, any quantity 1–``span`` of which the PLC must serve."""

    address: int
    span: int


class SerialClient(ModbusSerialClient):
    """pymodbus's RTU client with its port opened through :func:`hil.io.line.open_line`, so that an
    ``rfc2217://HOST:PORT`` port works: pymodbus's own ``connect()`` passes ``write_timeout`` (which pyserial's
    RFC 2217 client refuses with NotImplementedError) and then sets ``inter_byte_timeout`` (a renegotiation of every
    line setting).  Per request pymodbus only asks ``in_waiting`` and reads what it counts, which an RFC 2217 port
    answers from its local queue: nothing else goes to the server.  ``open_error``: why the last connect failed."""

    def __init__(self, port: str, **kwargs: object) -> None:
        super().__init__(port, **kwargs)  # type: ignore[arg-type]
        self.line: Line | None = None
        self.open_error = ""

    def connect(self) -> bool:
        if self.socket:
            return True
        p = self.comm_params
        try:
            self.line = open_line(p.host, baudrate=p.baudrate, bytesize=p.bytesize, parity=p.parity,
                                  stopbits=p.stopbits, timeout=p.timeout_connect, write_timeout=p.timeout_connect,
                                  exclusive=True)
        except TransportError as exc:
            self.open_error = str(exc)
            return False
        self.socket = self.line.port
        if isinstance(self.line, LocalLine):
            self.socket.inter_byte_timeout = self.inter_byte_timeout  # what pymodbus's connect() sets
        return True

    def close(self) -> None:
        if self.line is not None:
            self.line.close()  # without the sleeps of pyserial's socket:// and rfc2217:// close()
        self.line = None
        self.socket = None


class _Shape(Exception):
    """A reply that does not answer the request sent (wrong function, unit or quantity)."""


class _Stale(Exception):
    """A read's reply on RTU that could be a late or repeated reply to an earlier request (the fence failed)."""


class _Lost(TransportError):
    """A request whose reply never came or did not answer it (the request policy's to repeat or report)."""


class _NoReply(_Lost):
    """No reply within the timeout."""


Hooks = tuple[Callable[[bool, bytes], bytes], Callable[[bool, ModbusPDU], ModbusPDU]]  # trace_packet, trace_pdu


class ModbusWire:
    """A pymodbus sync client with the harness's request rules.  Build with :meth:`tcp` or :meth:`rtu`."""

    def __init__(self, build: Callable[[Hooks], ModbusTcpClient | ModbusSerialClient],
                 description: str, *, unit: int, timeout: float, retries: int, hint: str, probe: Probe,
                 describe: Describe | None = None, backoff: float = 0.05, fence: str = "trouble") -> None:
        if fence not in ("trouble", "reads"):
            raise InvalidValue(f"fence must be 'trouble' or 'reads', not {fence!r}")
        self.fence_every_read = fence == "reads"  # RTU only: TCP has transaction ids
        self.description = description
        self.unit = unit
        self.timeout = timeout
        self.retries = retries
        self.backoff = backoff
        self.policy = RequestPolicy(retries, float(backoff))  # one rule for every wire (hil.io.request_policy)
        self.probe = probe
        self.hint = hint
        self.describe = describe or (lambda table, address, count: f"{table} {address}×{count}")
        self.observers: list[Observer] = []
        self._received: list[bytes] = []  # what pymodbus held each time it tried to decode, since the request
        self._extra = 0  # RTU: bytes received since the request that were not the reply's frame
        self._probes = 0  # probe reads sent (resynchronisations and fences): the next quantity in turn
        self.fenced_out = 0  # RTU reads repeated because their fence failed
        self.client = build((self._trace_packet, self._trace_pdu))  # retries=0: we retry reads only
        self.serial = isinstance(self.client, ModbusSerialClient)
        self.kind = "modbus-rtu" if self.serial else "modbus-tcp"
        self.requests = 0  # Modbus requests sent (round trips)
        self.dirty = False  # True: a late reply may be on the line; recover before the next request
        self._abandoned: set[tuple[int, int]] = set()  # (fc, quantity) of requests given up since the last sync
        self._inflight: tuple[int, int] | None = None
        self.resyncs = 0
        self.reconnects = 0
        self._what = ""  # the request in hand (what a resync failure names)
        self._resync = Resync(needed=lambda: self.dirty, probe=lambda n, tries: self._probe(self._what),
                              failed=lambda last: (f"{self._what} not sent to {self.description}: the line could "
                                                   f"not be resynchronised after an earlier fault ({last})"))
        if not self.client.connect():
            self.client.close()
            nameless = None if self.serial else unresolved(getattr(self.client.comm_params, "host", None))
            raise TransportError(f"cannot connect to {description}: {self._open_error() or nameless or hint}")

    # -- constructors -----------------------------------------------------------------------------------------
    @classmethod
    def tcp(cls, host: str, port: int, *, unit: int, timeout: float, retries: int, hint: str, probe: Probe,
            description: str, describe: Describe | None = None) -> ModbusWire:
        return cls(lambda hooks: ModbusTcpClient(host, port=port, timeout=timeout, retries=0,
                                                 trace_packet=hooks[0], trace_pdu=hooks[1]),
                   description, unit=unit, timeout=timeout, retries=retries, hint=hint, probe=probe,
                   describe=describe)

    @classmethod
    def rtu(cls, device: str, *, baudrate: int, parity: str, bytesize: int, stopbits: int, unit: int,
            timeout: float, retries: int, hint: str, probe: Probe, label: str = "",
            describe: Describe | None = None, fence: str = "trouble") -> ModbusWire:
        """Modbus RTU on ``device`` (a path, or an RFC 2217 server's ``rfc2217://HOST:PORT``); ``hint``: what to check
        on the slave's side when it does not answer (the line's own checks come first), ``label``: added to the
        description (e.g. the address map)."""
        hint = f"{line_check(device)} {hint}"
        description = f"{serial_target('modbus', device)}?baudrate={baudrate}&parity={parity}&unit={unit}" + (
            f" ({label})" if label else "")
        return cls(lambda hooks: SerialClient(device, framer=FramerType.RTU, baudrate=baudrate, bytesize=bytesize,
                                              parity=parity, stopbits=stopbits, timeout=timeout, retries=0,
                                              trace_packet=hooks[0], trace_pdu=hooks[1]),
                   description, unit=unit, timeout=timeout, retries=retries, hint=hint, probe=probe,
                   describe=describe, fence=fence)

    # -- requests ---------------------------------------------------------------------------------------------
    def read(self, table: str, address: int, count: int) -> list[int]:
        """``count`` coils / discrete inputs (0/1) or holding registers from ``address``, in one request."""
        fc = READ_FC[table]
        if table == HOLDING:
            rr = self._exchange(fc, address, count, lambda: self.client.read_holding_registers(
                address, count=count, device_id=self.unit))
            return list(rr.registers)
        send = self.client.read_coils if table == COILS else self.client.read_discrete_inputs
        rr = self._exchange(fc, address, count, lambda: send(address, count=count, device_id=self.unit))
        return [1 if b else 0 for b in rr.bits[:count]]  # bits come padded to a multiple of 8

    def write(self, table: str, address: int, values: Sequence[int]) -> None:
        """Coils (0/1) or holding registers from ``address``, in one request; never repeated."""
        fc = WRITE_FC[table]
        if table == COILS:
            bits = [bool(v) for v in values]
            self._exchange(fc, address, len(bits), lambda: self.client.write_coils(address, bits,
                                                                                   device_id=self.unit))
        else:
            words = list(values)
            self._exchange(fc, address, len(words), lambda: self.client.write_registers(address, words,
                                                                                        device_id=self.unit))

    def budget(self, write: bool = False) -> float:
        """The longest one Modbus request can take, retries, backoff and recovery included."""
        fence = self.timeout if self.serial and self.fence_every_read and not write else 0.0
        # a probe: a probe read, or a new connection (0.5 s for pymodbus to close and connect)
        return self.policy.budget(self.timeout + fence, write, probe=self.timeout + 0.5)

    def reopen(self) -> None:
        """Close and reconnect the client (a new TCP connection, the serial port opened again)."""
        self.client.close()
        if not self.client.connect():
            raise TransportError(f"cannot reconnect to {self.description}: {self._open_error() or self.hint}")
        self.reconnects += 1
        self.dirty = self.serial  # a late reply may still come on a serial line

    def close(self) -> None:
        self.client.close()

    # -- the rules --------------------------------------------------------------------------------------------
    def _trace_packet(self, sending: bool, data: bytes) -> bytes:
        if not sending and self.serial:
            self._received.append(data)  # all pymodbus holds; it then decodes the first frame in it
        for observer in list(self.observers):
            observer("tx" if sending else "rx", data)
        return data

    def _trace_pdu(self, sending: bool, pdu: ModbusPDU) -> ModbusPDU:
        if sending:
            self._received.clear()
            self._extra = 0
        elif self.serial:
            # On RTU pymodbus drops what came with the first good frame and what it could not decode (a bad CRC):
            # a stale reply hides ours the first way, a corrupted reply of ours then lets a stale one in the
            # second.  Earlier holdings that are not the start of the last one were dropped.
            last, earlier = self._received[-1], self._received[:-1]
            self._extra = (len(last) - len(self.client.framer.buildFrame(pdu))
                           + sum(len(held) for held in earlier if not last.startswith(held)))
        return pdu

    def _probe(self, what: str) -> None:
        """After a fault, before the next request: on TCP a new connection (transaction ids guard the rest, but a
        stream with junk in it never re-frames); on RTU, which has no transaction id, a probe read whose reply has
        a quantity no abandoned request had — every reply before it is stale, and the line is in step again."""
        if not self.serial:
            try:
                self.reopen()
            except TransportError as exc:  # not a lost request: nothing can be sent at all
                raise TransportError(f"{what} not sent: {exc}") from None
            self.dirty = False
            return
        if not self.client.connected and not self.client.connect():
            # pymodbus closed the port when it failed (a server gone, an adapter unplugged): say why it cannot
            # be reopened rather than "no reply"
            raise TransportError(f"{what} not sent to {self.description}: cannot reopen the port: "
                                 f"{self._open_error() or self.hint}")
        used = {count for fc, count in self._abandoned | ({self._inflight} if self._inflight else set()) if fc == 3}
        self._flush()
        count, why = self._probe_read(used)
        if why:
            self._abandoned.add((3, count))
            raise _Lost(why)
        self.dirty = False
        self._abandoned.clear()
        self.resyncs += 1

    def _open_error(self) -> str:
        """Why the serial port did not open, with what to check (hil.io.line.open_line's message); "" for TCP."""
        return getattr(self.client, "open_error", "")

    def _flush(self) -> None:
        """Drop whatever is waiting on a serial line (a late reply) before a request: a local drain (on an RFC 2217
        port, of the client's queue — a purge on the server would cost a round trip of its own)."""
        line = getattr(self.client, "line", None)
        if line is not None:
            with contextlib.suppress(OSError, ValueError, serial.SerialException):
                line.discard()

    def _fence(self, fc: int, count: int) -> None:
        """On RTU, after a read's reply passed :meth:`_check`: prove it was not a late or repeated reply to an earlier
        request of the same shape (unit, function and byte count are all an RTU reply has).  Replies come in order,
        so a stale frame taken for ours leaves ours still to come: it shows up with the reply (pymodbus would drop
        it), waiting on the line after it, or before the answer to a probe read whose quantity differs from the
        read's.  Raises :class:`_Stale` (the read is repeated after a resynchronisation).  The probe read, a second
        round trip, only on a line that may repeat a reply (``fence_every_read``; docs/safety.md); on a direct line
        the reply must only have come alone.  On TCP the transaction id did it."""
        if not self.serial:
            return
        reason = self._stale_before_probe() or (self._stale_at_probe(fc, count) if self.fence_every_read else "")
        if reason:
            self.fenced_out += 1
            raise _Stale(reason)

    def _stale_before_probe(self) -> str:
        if self._extra > 0:
            return f"{self._extra} byte(s) more came with it or before it"
        line = getattr(self.client, "line", None)
        try:  # pymodbus drains the line before it sends the probe: look first
            waiting = line is not None and line.pending()
        except (OSError, ValueError, serial.SerialException):
            waiting = False
        return "bytes arrived right after it" if waiting else ""

    def _stale_at_probe(self, fc: int, count: int) -> str:
        probe, why = self._probe_read({count} if fc == 3 else set())
        if not why and self._extra:
            why = f"{self._extra} byte(s) more came with its answer"
        return f"the probe read of {probe} register(s) after it: {why}" if why else ""

    def _probe_read(self, avoid: set[int]) -> tuple[int, str]:
        """A probe read of a quantity not in ``avoid`` (each call the next one, in turn): (the quantity, "" when
        its answer came, else what went wrong: a reply with another quantity is a stale one)."""
        self._probes += 1
        choices = [c for c in range(1, self.probe.span + 1) if c not in avoid] or [1]
        count = choices[self._probes % len(choices)]
        try:
            rr = self.client.read_holding_registers(self.probe.address, count=count, device_id=self.unit)
        except ModbusException as exc:
            return count, f"no reply ({exc})"
        if rr.isError() or rr.function_code != 3 or rr.dev_id != self.unit or len(rr.registers) != count:
            return count, f"a stale reply (function {rr.function_code}) came first"
        return count, ""

    def _exchange(self, fc: int, address: int, count: int, send: Callable[[], ModbusPDU]) -> ModbusPDU:
        """One Modbus request under the request policy (:mod:`hil.io.request_policy`): this wire supplies one try
        (pymodbus's client sends and receives; :meth:`_check` and the fence judge the reply) and the probe
        (:meth:`_probe`).  Every failure becomes a harness error naming the request, the target and the fault."""
        table = {1: COILS, 2: DISCRETE_INPUTS, 3: HOLDING, 15: COILS, 16: HOLDING}[fc]
        what = f"{FC_NAMES[fc]} at {address} ×{count} ({self.describe(table, address, count)})"
        write = fc in (15, 16)

        def attempt(n: int, tries: int) -> ModbusPDU:
            self._flush()
            self.requests += 1
            # Suspect until the reply is in: an exchange cut short (pytest-timeout's signal, Ctrl-C) leaves its
            # reply on the way.
            self.dirty, self._inflight = True, (fc, count)
            try:
                rr = self._check(fc, address, count, what, send())
                if not write:
                    self._fence(fc, count)
            except PlcErrorReply:
                self.dirty, self._inflight = False, None  # an exception reply is still our reply
                raise
            except (ModbusException, _Shape, _Stale) as exc:
                self._abandoned.add((fc, count))
                fault = self._fault(exc, what, n, tries)
                raise (_NoReply if isinstance(exc, ModbusIOException) else _Lost)(fault) from None
            self.dirty, self._inflight = self._extra > 0, None  # more than the reply came: resync first
            return rr
        self._what = what
        return self.policy.run("", attempt, write=write, lost=(_Lost,), timeouts=(_NoReply,),
                               resync=self._resync, one_try=self.timeout)

    def _fault(self, exc: Exception, what: str, attempt: int, attempts: int) -> str:
        where = f"{what} on {self.description} (attempt {attempt} of {attempts})"
        if isinstance(exc, _Shape):
            return f"a reply of the wrong shape to {where}: {exc}"
        if isinstance(exc, _Stale):
            return (f"the reply to {where} could have been a late or repeated reply to an earlier request ({exc}), "
                    f"so its value was not trusted")
        if isinstance(exc, ModbusIOException):
            # pymodbus's own "No response received after 0 retries" counts differently from our attempts: drop it
            detail = "" if "No response received" in str(exc) else f" [pymodbus: {exc}]"
            return (f"no valid reply to {where} within {self.timeout:g} s: check the unit id, wiring/serial "
                    f"settings and that the PLC is powered{detail}")
        if isinstance(exc, ConnectionException):
            return f"lost the connection during {where}: {self.hint} [pymodbus: {exc}]"
        return f"{where} failed: {exc}"

    def _check(self, fc: int, address: int, count: int, what: str, rr: ModbusPDU) -> ModbusPDU:
        """The reply must answer exactly this request: our unit, our function, our quantity (and address)."""
        if rr.isError():
            if getattr(rr, "function_code", 0) & 0x7F != fc:
                raise _Shape(f"an exception reply to function {rr.function_code & 0x7F}")
            code = getattr(rr, "exception_code", None)
            meaning = EXCEPTION_NAMES.get(code, "unknown Modbus exception") if code is not None else "error reply"
            # (a server that is no gateway answers 10/11 for a unit id it does not serve: the likeliest cause)
            hint = (f"the server serves no unit {self.unit} — check the target's ?unit= (the PLC's Modbus unit id, "
                    f"usually 1)" if code in GATEWAY else "")
            raise PlcErrorReply(str(code), meaning, f"{what} on {self.description}", hint)
        if rr.function_code != fc:
            raise _Shape(f"function {rr.function_code} answered function {fc}")
        if rr.dev_id not in (0, self.unit):
            raise _Shape(f"unit {rr.dev_id} answered, expected {self.unit}")
        if fc == 3 and len(rr.registers) != count:
            raise _Shape(f"{len(rr.registers)} registers for {count} asked")
        if fc in (1, 2) and len(rr.bits) != (count + 7) // 8 * 8:
            raise _Shape(f"{len(rr.bits)} bits for {count} asked")
        if fc in (15, 16) and (rr.address != address or rr.count != count):
            raise _Shape(f"the write echo names {rr.count} at {rr.address}, sent {count} at {address}")
        return rr


class OverModbusWire:
    """Mixin for a family's link (a :class:`hil.core.link.Link`) whose requests go through a :class:`ModbusWire`:
    what it counts, what observes its frames, how it reconnects and closes are the wire's."""

    wire: ModbusWire
    _lock: Any  # the Link's: one request on the wire at a time

    def _use_wire(self, wire: ModbusWire) -> None:
        self.wire = wire
        self.unit = wire.unit
        self.timeout = wire.timeout
        self.retries = wire.retries
        self.serial = wire.serial
        self.observers = wire.observers  # every frame, "tx"/"rx" (wire traces, statistics)
        self.trace_kind = wire.kind

    # the wire counts requests (Link.__init__ assigns 0 before the wire is known: ignored)
    requests = property(lambda self: self.wire.requests, lambda self, value: None)
    resyncs = property(lambda self: self.wire.resyncs)
    # RTU on a line that may repeat replies: the read and its fence
    requests_per_read = property(lambda self: 2 if self.wire.serial and self.wire.fence_every_read else 1)
    reconnects = property(lambda self: self.wire.reconnects)
    client = property(lambda self: self.wire.client)

    def budget(self, write: bool = False) -> float:
        """The longest one Modbus request can take, retries, backoff and recovery included."""
        return self.wire.budget(write)

    def reopen(self) -> None:
        """Close and reconnect the client (a new TCP connection, the serial port opened again)."""
        with self._lock:
            self.wire.reopen()

    def _close(self) -> None:
        self.wire.close()
