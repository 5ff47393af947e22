"""The one engine-over-Modbus server: a scan engine (:class:`hil.sim.engine.Engine`) served over Modbus/TCP, or
RTU on a pty, by pymodbus's own server.  A family (or a fault rig) supplies only its address map
(:class:`ModbusMap`): which PDU addresses each table holds, which functions it answers, and what a request reads
or writes in the engine's memory.  Everything else holds for every map alike:

* **Requests at scan boundaries**: a SimDevice whose async ``action`` hands the map's request to
  :meth:`Engine.service`, so each one runs against live memory between two scans; the SimDevice's own tables are
  only a staging area (what a map does not fill is answered as it was last written there).
* **A request gate** (pymodbus's ``trace_pdu`` hook, which may replace a received request) answers what the
  controller refuses before the data store sees it: a function the map does not answer → exception 1; a quantity
  outside 1 … the protocol limit → exception 3; any unit outside the map's tables → exception 2 (pymodbus takes
  a bit table for one block, gaps included, so the gate checks every unit itself).  Another unit id: RTU stays
  silent, as a slave on a shared line must; TCP answers exception 0x0B (gateway target failed to respond) —
  [our choice], a clear answer instead of a timeout.  On TCP, unit ids 0 and FFH are this device too; unit 0 on
  RTU is broadcast (writes executed, never answered).  ``unit=None`` answers every unit id (a relay module).
* **Order and strict requests** (:mod:`hil.sim.modbus_server`): every request of a TCP segment answered in order,
  quantities checked strictly, FC05 only 0000H/FF00H, undecodable frames answered with their own function code.
* **Wire faults**: a :class:`~hil.sim.wire_faults.WireFaults` plan every reply goes through (TCP: a proxy in
  front of pymodbus's server, one MBAP frame a reply; RTU: the pty bridge).

``engine.stats`` counts ``<stats>_requests`` (every decoded request), ``<stats>_exceptions`` (exception replies
sent), ``<stats>_exception_<code>`` and ``<stats>_ignored`` (requests for another unit on RTU); ``stats`` is
"modbus" unless the server is told otherwise (a rig beside the PLC's own server counts apart).
"""

from __future__ import annotations

import asyncio
import bisect
import concurrent.futures
import threading
from collections.abc import Awaitable, Callable, Coroutine
from dataclasses import dataclass, field
from typing import Any, Protocol

from pymodbus.constants import ExcCodes
from pymodbus.datastore import ModbusServerContext
from pymodbus.exceptions import NoSuchIdException
from pymodbus.pdu import ExceptionResponse, ModbusPDU
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimAction, SimData, SimDevice

from hil.sim.engine import Engine
from hil.sim.modbus_server import STRICT_REQUESTS, InOrderTcpServer, tcp_unit_aliases
from hil.sim.pacing import LineRate
from hil.sim.ptypair import PtyPair
from hil.sim.runtime import LoopThread, ServerHandle
from hil.sim.wire_faults import FaultySender, WireFaults, corrupt_mbap

#: What a request does: run on the engine's memory at a scan boundary, it returns what fills the reply's staging
#: registers (called after the await, so no other request interleaves before pymodbus copies them).
Request = Callable[[Any], Callable[[], None]]
Values = list[int] | list[bool] | None

COILS, DISCRETE, HOLDING, INPUTS = range(4)  # pymodbus's SimDevice table order
#: function code → (table, is a write); FC05/06 write one unit whatever the PDU's count says
FUNCTIONS: dict[int, tuple[int, bool]] = {1: (COILS, False), 2: (DISCRETE, False), 3: (HOLDING, False),
                                          4: (INPUTS, False), 5: (COILS, True), 6: (HOLDING, True),
                                          15: (COILS, True), 16: (HOLDING, True)}
#: The specification's quantity limits per request (Modbus application protocol, section 6): bits, registers.
READ_LIMITS = {COILS: 2000, DISCRETE: 2000, HOLDING: 125, INPUTS: 125}
WRITE_LIMITS = {COILS: 1968, HOLDING: 123}


@dataclass(frozen=True)
class Tables:
    """The PDU address ranges ``[first, end)`` each table maps, sorted and disjoint (empty: no such table)."""

    coils: tuple[tuple[int, int], ...] = ()
    discrete: tuple[tuple[int, int], ...] = ()
    holding: tuple[tuple[int, int], ...] = ()
    inputs: tuple[tuple[int, int], ...] = ()
    _starts: tuple[tuple[int, ...], ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for ranges in self.in_order():
            if any(a >= b for a, b in ranges) or any(b > c for (_, b), (c, _) in zip(ranges, ranges[1:])):
                raise ValueError(f"table ranges must be non-empty, sorted and disjoint: {ranges}")
        object.__setattr__(self, "_starts", tuple(tuple(a for a, _ in r) for r in self.in_order()))

    def in_order(self) -> tuple[tuple[tuple[int, int], ...], ...]:
        return self.coils, self.discrete, self.holding, self.inputs

    def unmapped_in(self, table: int, address: int, count: int) -> int | None:
        """The first of ``count`` units from ``address`` that ``table`` does not map, or None if all are."""
        ranges, at, end = self.in_order()[table], address, address + count
        i = bisect.bisect_right(self._starts[table], at) - 1  # the last range that starts at or before ``at``
        while at < end:
            if i < 0 or i >= len(ranges) or ranges[i][0] > at or at >= ranges[i][1]:
                return at
            at, i = ranges[i][1], i + 1
        return None


class ModbusMap(Protocol):
    """What a family's address map tells the one server.  ``request`` is asked only for requests the gate let
    through (a function in ``functions``, a quantity within the limits, every unit inside ``tables``)."""

    tables: Tables
    functions: frozenset[int]

    def request(self, function_code: int, start_address: int, address: int, count: int, registers: list[int],
                set_values: Values) -> Request | ExcCodes | None:
        """What the request does (pymodbus's SimAction arguments: for bit tables ``registers`` are packed 16-bit
        words, ``count`` of them); an exception code to refuse it, touching nothing; None: answered from the
        staging tables as they are."""


def verdict(tables: Tables, functions: frozenset[int], fc: int, address: int, count: int) -> ExcCodes | None:
    """The exception a device with ``tables`` answers a request for its own unit with, or None to serve it.
    ``count`` is the PDU's (for FC15/16 pymodbus sets it from the frame's quantity field)."""
    if fc not in functions or fc not in FUNCTIONS:
        return ExcCodes.ILLEGAL_FUNCTION
    table, is_write = FUNCTIONS[fc]
    if fc in (5, 6):
        count = 1
    limit = (WRITE_LIMITS if is_write else READ_LIMITS).get(table, 0)
    if not 1 <= count <= limit:
        return ExcCodes.ILLEGAL_VALUE
    if tables.unmapped_in(table, address, count) is not None:
        return ExcCodes.ILLEGAL_ADDRESS
    return None


# Engine.service() can wait on the engine lock (a test advancing virtual time holds it), so it runs on worker
# threads: the shared loop keeps serving every other server meanwhile.
_SERVICE_POOL = concurrent.futures.ThreadPoolExecutor(max_workers=4, thread_name_prefix="hil-modbus-service")


# -- the SimDevice -------------------------------------------------------------------------------------------------
def build_device(engine: Engine, modbus_map: ModbusMap, unit: int | None) -> SimDevice:
    """A SimDevice whose four tables cover exactly ``modbus_map``'s, its requests served by ``engine``; ``unit``
    None: device id 0, which pymodbus answers for every unit id."""
    tables = modbus_map.tables

    def bits(ranges: tuple[tuple[int, int], ...]) -> list[SimData]:
        return [SimData(a, values=[False] * (b - a), datatype=DataType.BITS) for a, b in ranges]

    def registers(ranges: tuple[tuple[int, int], ...]) -> list[SimData]:
        return [SimData(a, count=b - a, values=0, datatype=DataType.REGISTERS) for a, b in ranges]
    # SimDevice wants every table non-empty: a map without one gets a placeholder the gate never lets through
    # (its functions are refused, or every address in it is unmapped)
    simdata = (bits(tables.coils) or [SimData(0, values=[False] * 16, datatype=DataType.BITS)],
               bits(tables.discrete) or [SimData(0, values=[False] * 16, datatype=DataType.BITS)],
               registers(tables.holding) or [SimData(0, count=1, datatype=DataType.INVALID)],
               registers(tables.inputs) or [SimData(0, count=1, datatype=DataType.INVALID)])
    return SimDevice(id=0 if unit is None else unit, simdata=simdata, action=_make_action(engine, modbus_map))


def _make_action(engine: Engine, modbus_map: ModbusMap) -> SimAction:
    lock = engine.lock
    # A read's request depends on nothing but these arguments (the map is fixed, the staging list is the
    # device's own), and a client repeats the same few reads: build each once.
    reads: dict[tuple[int, int, int, int], tuple[list[int], Request]] = {}

    async def action(function_code: int, start_address: int, address: int, count: int,
                     registers: list[int], set_values: Values) -> ExcCodes | None:
        key = (function_code, start_address, address, count)
        hit = reads.get(key) if set_values is None else None
        if hit is not None and hit[0] is registers:
            request = hit[1]
        else:
            built = modbus_map.request(function_code, start_address, address, count, registers, set_values)
            if built is None or isinstance(built, ExcCodes):
                return built
            request = built
            if set_values is None:
                if len(reads) >= 4096:  # a client sweeping the address space: stay bounded
                    reads.clear()
                reads[key] = (registers, request)
        # Fast path: the engine is free (the usual case), so service the request right here on the loop — a hop
        # to a worker thread and back costs more than the request.  Only when somebody holds the lock (a test
        # advancing virtual time) does the request wait on a worker, leaving the loop free.  In real time (hil
        # emulate) a request waits for the end of the scan in progress: always on a worker.
        if not engine.realtime and lock.acquire(blocking=False):
            try:  # holding the lock, realtime cannot turn on (run_realtime takes it to do so)
                fill = engine.service(request)
            finally:
                lock.release()
        else:
            fill = await asyncio.get_running_loop().run_in_executor(_SERVICE_POOL, engine.service, request)
        fill()  # after the await: no other request can interleave before pymodbus copies the staging registers
        return None
    return action


# -- the request gate ----------------------------------------------------------------------------------------------
class _Refusal(ModbusPDU):
    """Stands in for a refused request: its ``datastore_update`` answers an exception and touches nothing."""

    def __init__(self, request: ModbusPDU, code: ExcCodes | None) -> None:
        super().__init__(dev_id=request.dev_id, transaction_id=request.transaction_id)
        self.function_code = request.function_code
        self.code = code  # None: stay silent

    async def datastore_update(self, context: ModbusServerContext, device_id: int) -> ModbusPDU:
        if self.code is None:
            raise NoSuchIdException(f"unit {device_id}")  # with ignore_missing_devices: no reply at all
        return ExceptionResponse(self.function_code, self.code)


def _make_gate(engine: Engine, modbus_map: ModbusMap, unit: int | None, serial: bool,
               prefix: str) -> Callable[[bool, ModbusPDU], ModbusPDU]:
    stats = engine.stats  # only this loop thread writes the <prefix>_* keys, so no lock is needed
    tables, functions = modbus_map.tables, modbus_map.functions
    # (function code, address, count) → verdict: it depends on nothing else (the map is fixed; every ModbusPDU
    # has address and count), and a client repeats the same few requests: check each once
    verdicts: dict[tuple[int, int, int], ExcCodes | None] = {}
    # the unit ids this device answers (None: any): RTU 0 = broadcast; TCP 0/FFH = this device
    ours = None if unit is None else {unit, 0} if serial else {unit, *tcp_unit_aliases(unit)}
    requests, ignored, exceptions = f"{prefix}_requests", f"{prefix}_ignored", f"{prefix}_exceptions"

    def gate(sending: bool, pdu: ModbusPDU) -> ModbusPDU:
        if sending:
            if isinstance(pdu, ExceptionResponse):
                stats[exceptions] += 1
                stats[f"{prefix}_exception_{pdu.exception_code}"] += 1
            return pdu
        stats[requests] += 1
        if ours is not None and pdu.dev_id not in ours:
            if serial:
                stats[ignored] += 1
                return _Refusal(pdu, None)
            return _Refusal(pdu, ExcCodes.GATEWAY_NO_RESPONSE)
        key = (pdu.function_code, pdu.address, pdu.count)
        try:
            code = verdicts[key]
        except KeyError:
            if len(verdicts) >= 4096:  # a client sweeping the address space: stay bounded
                verdicts.clear()
            code = verdicts[key] = verdict(tables, functions, *key)
        return pdu if code is None else _Refusal(pdu, code)
    return gate


# -- servers -------------------------------------------------------------------------------------------------------
def start_tcp(engine: Engine, modbus_map: ModbusMap, host: str = "127.0.0.1", port: int = 0,
              unit: int | None = 1, *, faults: WireFaults | None = None, kind: str = "modbus-tcp",
              stats: str = "modbus") -> ServerHandle:
    """Serve ``engine`` with ``modbus_map`` as Modbus/TCP unit ``unit``; port 0 picks a free port (the handle's
    address has it).  ``faults``: pymodbus's server cannot be told to misbehave, so a small proxy in front of it
    passes requests through and sends every reply (one MBAP frame) through the wire-fault plan."""
    runtime = LoopThread.shared()
    aliases = {} if unit is None else tcp_unit_aliases(unit)

    async def start() -> tuple[ModbusTcpServer, asyncio.Server | None]:
        server = InOrderTcpServer(build_device(engine, modbus_map, unit), address=(host, 0 if faults else port),
                                  trace_pdu=_make_gate(engine, modbus_map, unit, False, stats), aliases=aliases)
        await server.serve_forever(background=True)
        proxy = None
        if faults is not None:
            inner = _bound_port(server.transport)
            proxy = await asyncio.start_server(_fault_proxy(host, inner, faults), host, port)
        return server, proxy

    server, proxy = runtime.run(start())
    actual = _bound_port(proxy or server.transport)

    async def stop() -> None:
        if proxy is not None:
            proxy.close()
        await server.shutdown()

    return ServerHandle(kind, f"{host}:{actual}", _stopper(runtime, stop))


def _fault_proxy(host: str, port: int,
                 faults: WireFaults) -> Callable[[asyncio.StreamReader, asyncio.StreamWriter], Awaitable[None]]:
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


def start_rtu_pty(engine: Engine, modbus_map: ModbusMap, unit: int = 1, *, faults: WireFaults | None = None,
                  line: LineRate | None = None, kind: str = "modbus-rtu", stats: str = "modbus") -> ServerHandle:
    """Serve ``engine`` with ``modbus_map`` as Modbus RTU unit ``unit`` on a pty; the handle's address is the path
    a client opens (``.ptys`` the bridge with its byte counters, ``.line`` its pace).

    The client's settings (baud rate, parity) mean nothing on a pty; any work.  ``line``: the bridge paces every
    character at that rate and frame, both ways (:mod:`hil.sim.pacing`); None: as fast as the pty copies.
    """
    runtime = LoopThread.shared()

    async def start() -> tuple[PtyPair, ModbusSerialServer]:
        pair = PtyPair(asyncio.get_running_loop(), gate_b_to_a=True, faults=faults, line=line)
        try:
            server = ModbusSerialServer(build_device(engine, modbus_map, unit), port=pair.path_a, baudrate=9600,
                                        parity="N", ignore_missing_devices=True, broadcast_enable=True,
                                        reconnect_delay=0.1, custom_pdu=STRICT_REQUESTS,
                                        trace_pdu=_make_gate(engine, modbus_map, unit, True, stats))
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

    handle = ServerHandle(kind, pair.path_b, _stopper(runtime, stop))
    handle.ptys = pair  # byte counters for tests
    handle.line = line
    return handle


def _bound_port(listener: object) -> int:
    """The port a listening server is bound to (pymodbus keeps its listener, an asyncio server, as ``.transport``)."""
    if not isinstance(listener, asyncio.Server):
        raise TypeError(f"not a listening asyncio server: {listener!r}")
    port: int = listener.sockets[0].getsockname()[1]
    return port


def _stopper(runtime: LoopThread, stop: Callable[[], Coroutine[Any, Any, None]]) -> Callable[[], None]:
    lock = threading.Lock()

    def run() -> None:
        with lock:
            if runtime.loop.is_closed() or not runtime.loop.is_running():
                return  # the loop is gone, and with it every socket and fd it served
            runtime.run(stop())
    return run


def nothing() -> None:
    """The fill of a write: the reply carries nothing from memory."""


__all__ = ["ModbusMap", "Request", "Tables", "build_device", "nothing", "start_rtu_pty", "start_tcp", "verdict"]
