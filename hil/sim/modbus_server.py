"""pymodbus's server, made to answer as the Modbus specification says where pymodbus 3.16 does not.

* **Every request of a TCP segment is answered, in order.**  pymodbus decodes one frame per segment and keeps the
  rest until more bytes arrive, so a client that sends two requests at once (pipelining, or Nagle joining two
  small writes) gets one reply.  :class:`InOrderTcpServer`'s connection handler decodes every complete frame and
  serves them one after another.
* **Unit ids 0 and 255 reach the device on TCP** (``aliases``): FFH is what Modbus/TCP clients send to a directly
  connected server, 0 is what others send; the reply echoes the unit id the request carried.
* **A bad quantity is exception 3 of the request's function**, not ``80H`` exception 1: pymodbus refuses to
  decode a read of 0 (or more than the limit) and answers function code 0.  :data:`STRICT_REQUESTS` decode any
  quantity and answer ``fc | 80H``, exception 3 (ILLEGAL DATA VALUE), as the specification's state diagrams do.
* **FC05 takes 0000H or FF00H only**; any other value is exception 3 (pymodbus takes anything non-zero as ON).
* A frame that cannot be decoded at all is answered with its own function code: exception 1 (ILLEGAL FUNCTION)
  for a function nobody implements, 3 for a known function whose data is malformed.

Only the public constructor arguments (``custom_pdu``, ``trace_pdu``) and one override of the connection handler
are used; the family's server decides everything else (which functions and addresses exist).
"""

from __future__ import annotations

import collections
import struct
from typing import Any

from pymodbus.constants import ExcCodes
from pymodbus.datastore import ModbusServerContext
from pymodbus.exceptions import ModbusIOException, NoSuchIdException
from pymodbus.pdu import ExceptionResponse, ModbusPDU
from pymodbus.pdu.bit_message import (
    ReadCoilsRequest,
    ReadDiscreteInputsRequest,
    WriteMultipleCoilsRequest,
    WriteSingleCoilRequest,
)
from pymodbus.pdu.register_message import ReadHoldingRegistersRequest, ReadInputRegistersRequest
from pymodbus.server import ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler

COIL_ON, COIL_OFF = 0xFF00, 0x0000
#: The specification's quantity limits (FC16's, 123, pymodbus checks itself).
QUANTITY_LIMITS = {1: 2000, 2: 2000, 3: 125, 4: 125, 15: 1968}


def _any_quantity(base: type[ModbusPDU]) -> type[ModbusPDU]:
    """``base`` whose decode keeps a quantity outside 1…limit (pymodbus raises), and whose reply to one is
    exception 3 of its own function code."""

    # (self: an instance of the subclass of ``base`` made below, which adds out_of_range)
    def decode(self: Any, data: bytes) -> None:
        try:
            base.decode(self, data)
        except ValueError:
            self.out_of_range = True  # address and count are set before pymodbus checks the count

    async def datastore_update(self: Any, context: ModbusServerContext, device_id: int) -> ModbusPDU:
        if getattr(self, "out_of_range", False) or not 1 <= self.count <= QUANTITY_LIMITS[self.function_code]:
            return ExceptionResponse(self.function_code, ExcCodes.ILLEGAL_VALUE)
        return await base.datastore_update(self, context, device_id)

    return type(f"Strict{base.__name__}", (base,), {"decode": decode, "datastore_update": datastore_update,
                                                     "__module__": __name__})


class StrictWriteSingleCoilRequest(WriteSingleCoilRequest):
    """FC05 whose value must be FF00H (ON) or 0000H (OFF)."""

    raw_value = COIL_ON

    def decode(self, data: bytes) -> None:
        super().decode(data)
        self.raw_value = struct.unpack(">H", data[2:4])[0]

    async def datastore_update(self, context: ModbusServerContext, device_id: int) -> ModbusPDU:
        if self.raw_value not in (COIL_ON, COIL_OFF):
            return ExceptionResponse(self.function_code, ExcCodes.ILLEGAL_VALUE)
        return await super().datastore_update(context, device_id)


#: ``custom_pdu=`` for a pymodbus server: the requests above in place of pymodbus's own.
STRICT_REQUESTS: list[type[ModbusPDU]] = [
    _any_quantity(ReadCoilsRequest), _any_quantity(ReadDiscreteInputsRequest),
    _any_quantity(ReadHoldingRegistersRequest), _any_quantity(ReadInputRegistersRequest),
    _any_quantity(WriteMultipleCoilsRequest), StrictWriteSingleCoilRequest,
]
_KNOWN_FUNCTIONS = frozenset({1, 2, 3, 4, 5, 6, 7, 8, 11, 12, 15, 16, 17, 20, 21, 22, 23, 24, 43})


class _InOrderHandler(ServerRequestHandler):
    """One TCP connection: every complete frame of a segment decoded, then served one after another."""

    def __init__(self, owner: InOrderTcpServer, *args: Any) -> None:
        super().__init__(owner, *args)
        self.pending: collections.deque[tuple[ModbusPDU, tuple | None]] = collections.deque()
        self.serving = False

    def callback_data(self, data: bytes, addr: tuple | None = None) -> int:
        used = 0
        while used < len(data):
            rest = data[used:]
            try:
                n = super(ServerRequestHandler, self).callback_data(rest, addr)  # decode one frame, no serving
            except ModbusIOException:
                n = self._refuse_undecodable(rest, addr)
            else:
                if self.last_pdu is not None:
                    self.pending.append((self.last_pdu, addr))
            if n <= 0:
                break  # an incomplete frame: wait for the rest
            used += n
        if self.pending and not self.serving:
            self.serving = True
            self.loop.create_task(self._serve())
        return used

    def _refuse_undecodable(self, rest: bytes, addr: tuple | None) -> int:
        """An MBAP frame pymodbus cannot decode: the exception of its own function code."""
        if len(rest) < 8:
            return len(rest)
        size = 6 + int.from_bytes(rest[4:6], "big")
        tid, unit, fc = int.from_bytes(rest[0:2], "big"), rest[6], rest[7]
        code = ExcCodes.ILLEGAL_VALUE if fc in _KNOWN_FUNCTIONS else ExcCodes.ILLEGAL_FUNCTION
        reply = ExceptionResponse(fc & 0x7F, code, device_id=unit, transaction=tid)
        self.pending.append((_Canned(reply), addr))
        return size

    async def _serve(self) -> None:
        try:
            while self.pending:
                pdu, addr = self.pending.popleft()
                reply = await self._answer(pdu)
                if reply is not None:
                    reply.transaction_id = pdu.transaction_id
                    reply.dev_id = pdu.dev_id  # the unit id the request carried (0 and FFH included)
                    self.server_send(reply, addr)
        finally:
            self.serving = False

    async def _answer(self, pdu: ModbusPDU) -> ModbusPDU | None:
        server: InOrderTcpServer = self.server
        try:
            # pymodbus's own request handler passes the same context, which may be a SimCore
            context = server.context
            return await pdu.datastore_update(context,  # type: ignore[arg-type]  # its annotation names no SimCore
                                              server.aliases.get(pdu.dev_id, pdu.dev_id))
        except NoSuchIdException:
            if server.ignore_missing_devices:
                return None
            return ExceptionResponse(pdu.function_code, ExcCodes.GATEWAY_NO_RESPONSE)
        except Exception:  # noqa: BLE001 - a server never dies of one request (pymodbus answers the same)
            return ExceptionResponse(pdu.function_code, ExcCodes.DEVICE_FAILURE)


class _Canned(ModbusPDU):
    """A reply decided before the data store: its ``datastore_update`` returns it."""

    def __init__(self, reply: ExceptionResponse) -> None:
        super().__init__(dev_id=reply.dev_id, transaction_id=reply.transaction_id)
        self.function_code = reply.function_code
        self.reply = reply

    async def datastore_update(self, context: ModbusServerContext, device_id: int) -> ModbusPDU:
        return self.reply


class InOrderTcpServer(ModbusTcpServer):
    """``ModbusTcpServer`` that answers every request of a segment in order, with :data:`STRICT_REQUESTS`;
    ``aliases`` maps unit ids to the device that serves them (``{0: 1, 255: 1}``)."""

    def __init__(self, *args: Any, aliases: dict[int, int] | None = None, **kwargs: Any) -> None:
        kwargs["custom_pdu"] = [*STRICT_REQUESTS, *(kwargs.get("custom_pdu") or ())]
        super().__init__(*args, **kwargs)
        self.aliases = dict(aliases or {})

    def callback_new_connection(self) -> _InOrderHandler:
        return _InOrderHandler(self, self.trace_packet, self.trace_pdu, self.trace_connect)


def tcp_unit_aliases(unit: int) -> dict[int, int]:
    """Unit ids a Modbus/TCP server answers as ``unit`` besides itself: 0 and FFH (the "directly connected" ids)."""
    return {alias: unit for alias in (0, 0xFF) if alias != unit}


__all__ = ["InOrderTcpServer", "STRICT_REQUESTS", "StrictWriteSingleCoilRequest", "tcp_unit_aliases"]
