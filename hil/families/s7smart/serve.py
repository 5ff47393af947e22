"""Serve an S7 emulator over Modbus/TCP with the S7-200 SMART map, on pymodbus's server.

Same pattern as :mod:`hil.families.fbs.sim.serve_modbus` (a SimDevice whose async ``action`` forwards every request into
:meth:`hil.sim.engine.Engine.service`, so it is handled at a scan boundary), but with the S7 tables: holding registers = V
words from HoldStart (MaxHold of them), coils = Q0.0–Q31.7, discrete inputs = I0.0–I31.7, input registers =
AIW0–AIW110 (read as 0: the emulator has no analog inputs).  Only the function codes MBUS_SLAVE supports are
answered (01, 02, 03, 04, 05, 06, 15, 16); pymodbus answers ILLEGAL_ADDRESS outside the tables itself.
"""

from __future__ import annotations

import asyncio
import concurrent.futures

from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from hil.sim.runtime import LoopThread, ServerHandle
from hil.families.s7smart.emulator import S7Emulator, S7Memory
from hil.families.s7smart.modbus_map import BITS, INPUT_REGISTERS, S7ModbusMap, from_words, to_words

_POOL = concurrent.futures.ThreadPoolExecutor(max_workers=4, thread_name_prefix="hil-s7-modbus-service")
_BIT_FCS = {1: "Q", 2: "I", 5: "Q", 15: "Q"}
_REGISTER_FCS = (3, 6, 16)


def build_s7_device(emulator: S7Emulator, unit: int, modbus_map: S7ModbusMap) -> SimDevice:
    coils = [SimData(0, values=[False] * BITS, datatype=DataType.BITS)]
    discrete = [SimData(0, values=[False] * BITS, datatype=DataType.BITS)]
    holding = [SimData(0, count=modbus_map.max_hold, values=0, datatype=DataType.REGISTERS)]
    inputs = [SimData(0, count=INPUT_REGISTERS, values=0, datatype=DataType.REGISTERS)]
    return SimDevice(id=unit, simdata=(coils, discrete, holding, inputs),
                     action=_make_action(emulator, modbus_map))


def _make_action(emulator: S7Emulator, modbus_map: S7ModbusMap):  # noqa: ANN202 - a pymodbus SimAction
    async def action(function_code: int, start_address: int, address: int, count: int,
                     registers: list[int], set_values: list[int] | list[bool] | None) -> ExcCodes | None:
        if function_code in _BIT_FCS:
            request = _bits(_BIT_FCS[function_code], start_address, address, count, registers, set_values)
        elif function_code in _REGISTER_FCS:
            request = _holding(modbus_map, start_address, address, count, registers, set_values)
        elif function_code == 4:
            return None  # AIW: zeros from the staging table
        else:
            return ExcCodes.ILLEGAL_FUNCTION
        fill = await asyncio.get_running_loop().run_in_executor(_POOL, emulator.service, request)
        fill()  # after the await: no other request can interleave before pymodbus copies the reply
        return None
    return action


def _bits(area: str, start_address: int, address: int, count: int, registers: list[int], set_values):  # noqa: ANN001, ANN202
    if set_values is not None:
        values = [1 if v else 0 for v in set_values]

        def write(mem: S7Memory):  # noqa: ANN202
            bank = mem.areas[area]
            for n, v in enumerate(values, address):
                bank[n // 8] = bank[n // 8] | 1 << n % 8 if v else bank[n // 8] & ~(1 << n % 8)
            return lambda: None
        return write
    first_reg = address // 16  # pymodbus hands bit tables to the action as packed 16-bit registers
    offset = first_reg - start_address

    def read(mem: S7Memory):  # noqa: ANN202
        bank = mem.areas[area]
        words = [0] * count
        for r in range(count):
            for b in range(16):
                n = (first_reg + r) * 16 + b
                if n < BITS:
                    words[r] |= (bank[n // 8] >> n % 8 & 1) << b

        def fill() -> None:
            registers[offset:offset + count] = words
        return fill
    return read


def _holding(modbus_map: S7ModbusMap, start_address: int, address: int, count: int, registers: list[int],
             set_values):  # noqa: ANN001, ANN202
    first_byte = modbus_map.v_byte(address)
    if set_values is not None:
        data = from_words([int(v) for v in set_values])

        def write(mem: S7Memory):  # noqa: ANN202
            mem.write_bytes("V", first_byte, data)
            return lambda: None
        return write
    offset = address - start_address

    def read(mem: S7Memory):  # noqa: ANN202
        words = to_words(mem.read_bytes("V", first_byte, 2 * count))

        def fill() -> None:
            registers[offset:offset + count] = words
        return fill
    return read


def start_s7_modbus_tcp(emulator: S7Emulator, modbus_map: S7ModbusMap, host: str = "127.0.0.1", port: int = 0,
                        unit: int = 1) -> ServerHandle:
    """Serve ``emulator`` as Modbus/TCP unit ``unit`` with the S7-200 SMART map; port 0 picks a free port."""
    runtime = LoopThread.shared()

    async def start() -> ModbusTcpServer:
        server = ModbusTcpServer(build_s7_device(emulator, unit, modbus_map), address=(host, port))
        await server.serve_forever(background=True)
        return server

    server = runtime.run(start())
    actual = server.transport.sockets[0].getsockname()[1]

    def stop() -> None:
        if runtime.loop.is_closed() or not runtime.loop.is_running():
            return

        async def shutdown() -> None:
            await server.shutdown()
        runtime.run(shutdown())

    return ServerHandle("s7-modbus-tcp", f"{host}:{actual}", stop)
