"""Serve the emulator over Modbus (TCP, and RTU on a pty) with pymodbus's own server.

The server is pymodbus's: a :class:`SimDevice` whose four tables cover exactly the default FBs map
(:mod:`hil.families.fbs.protocol.modbus_map`), and an async ``action`` that forwards every read and write into
:meth:`Emulator.service` — so each request is handled at a scan boundary against live memory; the SimDevice's own
registers are only a staging area.

A request gate (pymodbus's ``trace_pdu`` hook, which may replace a received request) answers what an FBs
would refuse before the data store sees it:

* function codes other than 01/03/05/06/15/16 → exception 1 (illegal function), as the FBs supports only those;
* a quantity beyond the protocol limits → exception 3 (illegal data value);
* any unit outside the map → exception 2 (illegal data address).  pymodbus marks holes between holding blocks
  itself, but a bit table is one block to it (gaps read as 0), so the gate checks coils exactly;
* another unit id: RTU stays silent, as a slave on a shared line must; TCP answers exception 0x0B
  (gateway target failed to respond) — [our choice], a clear answer instead of a timeout.  On TCP, unit ids 0
  and FFH are this PLC too (FFH is what Modbus/TCP clients send to a directly connected server); the reply
  echoes the id the request carried;
* unit 0 on RTU is broadcast: writes are executed and never answered.

The TCP server is :class:`hil.sim.modbus_server.InOrderTcpServer`: every request of a segment is answered in
order, a quantity of 0 or over the limit is exception 3 of the request's function, FC05 takes only 0000H/FF00H.

``emulator.stats`` counts ``modbus_requests`` (every decoded request), ``modbus_exceptions`` (exception replies
sent), ``modbus_exception_<code>`` and ``modbus_ignored`` (requests for another unit on RTU).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import functools
import threading
from typing import Callable

from pymodbus.constants import ExcCodes
from pymodbus.exceptions import NoSuchIdException
from pymodbus.pdu import ExceptionResponse, ModbusPDU
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from hil.families.fbs.address import WORD_BANKS as _WORD_BANKS
from hil.families.fbs.address import Address
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.sim.memory import Memory
from hil.sim.modbus_server import STRICT_REQUESTS, InOrderTcpServer, tcp_unit_aliases
from hil.sim.pacing import LineRate
from hil.sim.ptypair import PtyPair
from hil.sim.runtime import LoopThread, ServerHandle
from hil.sim.wire_faults import FaultySender, WireFaults, corrupt_mbap
from hil.families.fbs.protocol.modbus_map import COIL, HOLDING, MAX_READ, MAX_WRITE, segments, unmapped_in
from hil.families.fbs.protocol.modbus_map import locate as _locate_uncached

#: (table, pdu) → (element, part): the map is fixed, and a walk of its segments per unit was a fifth of the cost
#: of a request.  Addresses are immutable, so sharing them is safe.
locate = functools.lru_cache(maxsize=1 << 16)(_locate_uncached)
_unmapped_in = functools.lru_cache(maxsize=1 << 12)(unmapped_in)  # the gate asks on every request

_COIL_FCS = {1: "read", 5: "write", 15: "write"}
_HOLDING_FCS = {3: "read", 6: "write", 16: "write"}
# Emulator.service() can wait on the emulator lock (a test advancing virtual time holds it), so it runs on
# worker threads: the shared loop keeps serving every other server meanwhile.
_SERVICE_POOL = concurrent.futures.ThreadPoolExecutor(max_workers=4, thread_name_prefix="hil-modbus-service")


# -- the SimDevice -------------------------------------------------------------------------------------------------
def build_device(emulator: Emulator, unit: int) -> SimDevice:
    """A SimDevice whose coil and holding tables cover exactly the default FBs map, backed by ``emulator``."""
    coils = [SimData(s.pdu, values=[False] * (s.pdu_end - s.pdu), datatype=DataType.BITS) for s in segments(COIL)]
    holding = [SimData(s.pdu, count=s.pdu_end - s.pdu, values=0, datatype=DataType.REGISTERS)
               for s in segments(HOLDING)]
    # The FBs has no discrete inputs or input registers (X are coils); the gate refuses FC02/FC04 before these
    # placeholders (required non-empty by SimDevice) could be reached.
    discrete = [SimData(0, values=[False] * 16, datatype=DataType.BITS)]
    inputs = [SimData(0, count=1, datatype=DataType.INVALID)]
    return SimDevice(id=unit, simdata=(coils, discrete, holding, inputs), action=_make_action(emulator))


def _make_action(emulator: Emulator):  # noqa: ANN202 - a pymodbus SimAction
    lock = emulator.lock
    # A read's request function depends on nothing but these arguments (the map is fixed, the staging list is
    # the device's own), and a client repeats the same few reads: build each once.
    reads: dict[tuple[int, int, int, int], tuple[list[int], Callable[[Memory], Callable[[], None]]]] = {}

    async def action(function_code: int, start_address: int, address: int, count: int,
                     registers: list[int], set_values: list[int] | list[bool] | None) -> ExcCodes | None:
        key = (function_code, start_address, address, count)
        hit = reads.get(key) if set_values is None else None
        if hit is not None and hit[0] is registers:
            request = hit[1]
        elif function_code in _COIL_FCS:
            request = _coil_request(start_address, address, count, registers, set_values)
        elif function_code in _HOLDING_FCS:
            request = _holding_request(start_address, address, count, registers, set_values)
        else:
            return ExcCodes.ILLEGAL_FUNCTION
        if set_values is None and hit is None:
            if len(reads) >= 4096:  # a client sweeping the address space: stay bounded
                reads.clear()
            reads[key] = (registers, request)
        # Fast path: the emulator is free (the usual case), so service the request right here on the loop —
        # a hop to a worker thread and back costs more than the request.  Only when somebody holds the lock
        # (a test advancing virtual time) does the request wait on a worker, leaving the loop free.
        # In real time (hil emulate) a request waits for the end of the scan in progress: always on a worker.
        if not emulator.realtime and lock.acquire(blocking=False):
            try:  # holding the lock, realtime cannot turn on (run_realtime takes it to do so)
                fill = emulator.service(request)
            finally:
                lock.release()
        else:
            fill = await asyncio.get_running_loop().run_in_executor(_SERVICE_POOL, emulator.service, request)
        # Fill the staging registers only now, after the await, so no other request can interleave before
        # pymodbus copies them into the reply.
        fill()
        return None
    return action


@functools.lru_cache(maxsize=1 << 12)
def _coil_slots(first_reg: int, count: int) -> tuple[tuple[int, int, str, int], ...]:
    """(register, bit, kind, index) of every mapped coil in ``count`` packed registers from ``first_reg``."""
    slots = ((r, b, locate(COIL, (first_reg + r) * 16 + b)) for r in range(count) for b in range(16))
    return tuple((r, b, found[0].kind, found[0].index) for r, b, found in slots if found is not None)


@functools.lru_cache(maxsize=1 << 12)
def _holding_slots(address: int, n: int) -> tuple[tuple[str, int, int | None], ...]:
    """(kind, index, part) of each of ``n`` registers from ``address``; part is None for a 16-bit element, 0/1 for
    the low/high word of a DRC; kind "" for a hole (the gate refuses those; stay safe regardless)."""
    slots = []
    for i in range(n):
        found = locate(HOLDING, address + i)
        if found is None:
            slots.append(("", 0, None))
        else:
            element, part = found
            slots.append((element.kind, element.index, part if element.kind == "DRC" else None))
    return tuple(slots)


@functools.lru_cache(maxsize=1 << 12)
def _holding_run(address: int, n: int) -> tuple[str, int] | None:
    """(kind, first index) when the ``n`` registers from ``address`` are consecutive 16-bit elements of one word
    bank, else None."""
    slots = _holding_slots(address, n)
    kind, first, _part = slots[0]
    if kind and kind in _WORD_BANKS and all(s == (kind, first + i, None) for i, s in enumerate(slots)):
        return kind, first
    return None


def _coil_request(start_address: int, address: int, count: int, registers: list[int],
                  set_values: list[int] | list[bool] | None) -> Callable[[Memory], Callable[[], None]]:
    """For coils pymodbus passes ``count`` packed 16-bit registers covering the request, from bit ``address``."""
    if set_values is not None:
        targets = [locate(COIL, address + i) for i in range(len(set_values))]
        values = [1 if v else 0 for v in set_values]

        def write(mem: Memory) -> Callable[[], None]:
            for found, value in zip(targets, values):
                if found is not None:  # the gate refused unmapped coils; stay safe regardless
                    mem.bits[found[0].kind][found[0].index] = value
            return _nothing
        return write

    first_reg = address // 16
    slots = _coil_slots(first_reg, count)
    offset = first_reg - start_address

    def read(mem: Memory) -> Callable[[], None]:
        words = [0] * count
        bits = mem.bits
        for r, b, kind, index in slots:
            words[r] |= bits[kind][index] << b

        def fill() -> None:
            registers[offset:offset + count] = words
        return fill
    return read


def _nothing() -> None:
    return None


def _holding_request(start_address: int, address: int, count: int, registers: list[int],
                     set_values: list[int] | list[bool] | None) -> Callable[[Memory], Callable[[], None]]:
    n = len(set_values) if set_values is not None else count
    slots = _holding_slots(address, n)
    if set_values is not None:
        values = [int(v) & 0xFFFF for v in set_values]

        def write(mem: Memory) -> Callable[[], None]:
            for (kind, index, part), value in zip(slots, values):
                if kind:
                    _set_register(mem, kind, index, part, value)
            return _nothing
        return write

    offset = address - start_address
    run = _holding_run(address, n)
    if run is not None:  # the usual read: one slice of one word bank
        kind, first = run
        end = first + n

        def read_run(mem: Memory) -> Callable[[], None]:
            values = mem.words[kind][first:end]

            def fill() -> None:
                registers[offset:offset + count] = values
            return fill
        return read_run

    def read(mem: Memory) -> Callable[[], None]:
        words = mem.words
        values = [(words[kind][index] if part is None else mem.get(Address(kind, index)) >> (16 * part) & 0xFFFF)
                  if kind else 0 for kind, index, part in slots]

        def fill() -> None:
            registers[offset:offset + count] = values
        return fill
    return read


def _set_register(mem: Memory, kind: str, index: int, part: int | None, value: int) -> None:
    if part is not None:  # half of a 32-bit counter: writing one keeps the other, as two FC06 writes must compose
        element = Address(kind, index)
        old = mem.get(element)
        mem.set(element, old & ~(0xFFFF << (16 * part)) | value << (16 * part))
    else:
        mem.words[kind][index] = value


# -- the request gate ----------------------------------------------------------------------------------------------
class _Refusal(ModbusPDU):
    """Stands in for a refused request: its ``datastore_update`` answers an exception and touches nothing."""

    def __init__(self, request: ModbusPDU, code: ExcCodes | None) -> None:
        super().__init__(dev_id=request.dev_id, transaction_id=request.transaction_id)
        self.function_code = request.function_code
        self.code = code  # None: stay silent

    async def datastore_update(self, context, device_id: int) -> ModbusPDU:  # noqa: ANN001
        if self.code is None:
            raise NoSuchIdException(f"unit {device_id}")  # with ignore_missing_devices: no reply at all
        return ExceptionResponse(self.function_code, self.code)


def _request_extent_of(fc: int, address: int, count: int) -> tuple[str, int, int, bool] | None:
    """(table, address, count, is_write) of a request the FBs supports, else None.  ``count`` is the PDU's (for
    FC15/16 decode() sets it from the frame's quantity field; FC05/06 write one unit whatever it says)."""
    if fc in (5, 6):
        return (COIL if fc == 5 else HOLDING), address, 1, True
    if fc in (15, 16):
        return (COIL if fc == 15 else HOLDING), address, count, True
    if fc in (1, 3):
        return (COIL if fc == 1 else HOLDING), address, count, False
    return None


def _verdict(fc: int, address: int, count: int) -> ExcCodes | None:
    """The exception an FBs answers a request for its own unit with, or None to serve it."""
    extent = _request_extent_of(fc, address, count)
    if extent is None:
        return ExcCodes.ILLEGAL_FUNCTION
    table, address, count, is_write = extent
    limit = (MAX_WRITE if is_write else MAX_READ)[table]
    if not 1 <= count <= limit:
        return ExcCodes.ILLEGAL_VALUE
    if _unmapped_in(table, address, count) is not None:
        return ExcCodes.ILLEGAL_ADDRESS
    return None


def _make_gate(emulator: Emulator, unit: int, serial: bool) -> Callable[[bool, ModbusPDU], ModbusPDU]:
    stats = emulator.stats  # only this loop thread writes the modbus_* keys, so no lock is needed
    # (function code, address, count) → verdict: the verdict depends on nothing else (the map is fixed; every
    # ModbusPDU has address and count), and a client repeats the same few requests: check each once
    verdicts: dict[tuple[int, int, int], ExcCodes | None] = {}
    ours = {unit, 0} if serial else {unit, *tcp_unit_aliases(unit)}  # RTU 0 = broadcast; TCP 0/FFH = this PLC

    def gate(sending: bool, pdu: ModbusPDU) -> ModbusPDU:
        if sending:
            if isinstance(pdu, ExceptionResponse):
                stats["modbus_exceptions"] += 1
                stats[f"modbus_exception_{pdu.exception_code}"] += 1
            return pdu
        stats["modbus_requests"] += 1
        if pdu.dev_id not in ours:
            if serial:
                stats["modbus_ignored"] += 1
                return _Refusal(pdu, None)
            return _Refusal(pdu, ExcCodes.GATEWAY_NO_RESPONSE)
        key = (pdu.function_code, pdu.address, pdu.count)
        try:
            code = verdicts[key]
        except KeyError:
            if len(verdicts) >= 4096:  # a client sweeping the address space: stay bounded
                verdicts.clear()
            code = verdicts[key] = _verdict(*key)
        return pdu if code is None else _Refusal(pdu, code)
    return gate


# -- servers -------------------------------------------------------------------------------------------------------
def start_modbus_tcp(emulator: Emulator, host: str = "127.0.0.1", port: int = 0, unit: int = 1, *,
                     faults: WireFaults | None = None) -> ServerHandle:
    """Serve ``emulator`` as Modbus/TCP unit ``unit``; port 0 picks a free port (the handle's address has it).

    ``faults``: pymodbus's server cannot be told to misbehave, so a small proxy in front of it passes requests
    through and sends every reply (one MBAP frame) through the wire-fault plan."""
    runtime = LoopThread.shared()

    async def start() -> tuple[ModbusTcpServer, asyncio.AbstractServer | None]:
        server = InOrderTcpServer(build_device(emulator, unit), address=(host, 0 if faults else port),
                                  trace_pdu=_make_gate(emulator, unit, serial=False),
                                  aliases=tcp_unit_aliases(unit))
        await server.serve_forever(background=True)
        proxy = None
        if faults is not None:
            inner = server.transport.sockets[0].getsockname()[1]
            proxy = await asyncio.start_server(_fault_proxy(host, inner, faults), host, port)
        return server, proxy

    server, proxy = runtime.run(start())
    actual = (proxy.sockets if proxy else server.transport.sockets)[0].getsockname()[1]

    async def stop() -> None:
        if proxy is not None:
            proxy.close()
        await server.shutdown()

    return ServerHandle("modbus-tcp", f"{host}:{actual}", _stopper(runtime, stop))


def _fault_proxy(host: str, port: int, faults: WireFaults):  # noqa: ANN202 - an asyncio client callback
    async def client(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            up_reader, up_writer = await asyncio.open_connection(host, port)
        except OSError:
            writer.close()
            return

        def hangup() -> None:
            writer.close()
            up_writer.close()
        sender = FaultySender(faults, writer.write, corrupt_mbap, close=hangup)

        async def requests() -> None:
            while data := await reader.read(4096):
                up_writer.write(data)
            up_writer.close()

        async def replies() -> None:
            buffer = b""
            while data := await up_reader.read(4096):
                buffer += data
                while len(buffer) >= 6 and len(buffer) >= 6 + int.from_bytes(buffer[4:6], "big"):
                    size = 6 + int.from_bytes(buffer[4:6], "big")
                    sender.send(buffer[:size])  # one MBAP frame = one reply
                    buffer = buffer[size:]
        tasks = [asyncio.ensure_future(requests()), asyncio.ensure_future(replies())]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        except (ConnectionError, OSError):
            pass
        finally:
            for task in tasks:
                task.cancel()
            sender.stop()
            writer.close()
            up_writer.close()
    return client


def start_modbus_rtu_pty(emulator: Emulator, unit: int = 1, *, faults: WireFaults | None = None,
                         line: LineRate | None = None) -> ServerHandle:
    """Serve ``emulator`` as Modbus RTU unit ``unit`` on a pty; the handle's address is the path a client opens.

    The client's settings (baud rate, parity) mean nothing on a pty; any work.  ``line``: the bridge paces every
    character at that rate and frame, both ways (:mod:`hil.sim.pacing`); None: as fast as the pty copies.
    """
    runtime = LoopThread.shared()

    async def start() -> tuple[PtyPair, ModbusSerialServer]:
        pair = PtyPair(asyncio.get_running_loop(), gate_b_to_a=True, faults=faults, line=line)
        try:
            server = ModbusSerialServer(build_device(emulator, unit), port=pair.path_a, baudrate=9600, parity="N",
                                        ignore_missing_devices=True, broadcast_enable=True, reconnect_delay=0.1,
                                        trace_pdu=_make_gate(emulator, unit, serial=True),
                                        custom_pdu=STRICT_REQUESTS)
            await server.serve_forever(background=True)
        except BaseException:
            pair.close()
            raise
        return pair, server

    pair, server = runtime.run(start())

    async def stop() -> None:
        try:
            await server.shutdown()
        finally:
            pair.close()

    handle = ServerHandle("modbus-rtu", pair.path_b, _stopper(runtime, stop))
    handle.ptys = pair  # type: ignore[attr-defined]  # byte counters for tests
    handle.line = line  # type: ignore[attr-defined]
    return handle


def _stopper(runtime: LoopThread, stop: Callable[[], "asyncio.Future | object"]) -> Callable[[], None]:
    lock = threading.Lock()

    def run() -> None:
        with lock:
            if runtime.loop.is_closed() or not runtime.loop.is_running():
                return  # the loop is gone, and with it every socket and fd it served
            runtime.run(stop())
    return run


__all__ = ["start_modbus_tcp", "start_modbus_rtu_pty", "build_device"]
