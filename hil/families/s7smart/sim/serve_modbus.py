"""Serve an S7 emulator over Modbus/TCP: the S7-200 SMART map for the one engine-over-Modbus server
(:mod:`hil.sim.modbus_engine`).

The tables are the MBUS_SLAVE library's: holding registers = V words from HoldStart (MaxHold of them), coils =
Q0.0–Q31.7, discrete inputs = I0.0–I31.7, input registers = AIW0–AIW110 (read as 0: the emulator has no analog
inputs); only the function codes MBUS_SLAVE supports are answered (01, 02, 03, 04, 05, 06, 15, 16).  Requests at
scan boundaries, the request gate (exceptions 1, 2, 3, unit ids), in-order TCP, strict quantities and wire
faults are the one server's, as for the FBs.
"""

from __future__ import annotations

from collections.abc import Callable

from pymodbus.constants import ExcCodes
from pymodbus.simulator import SimDevice

from hil.families.s7smart.protocol.modbus_map import BITS, INPUT_REGISTERS, S7ModbusMap, from_words, to_words
from hil.families.s7smart.sim.cpu import S7Emulator
from hil.families.s7smart.sim.memory import S7Memory
from hil.sim.modbus_engine import Request, Tables, Values, build_device, nothing, start_tcp
from hil.sim.runtime import ServerHandle
from hil.sim.wire_faults import WireFaults

_BIT_FCS = {1: "Q", 2: "I", 5: "Q", 15: "Q"}
_REGISTER_FCS = (3, 6, 16)


class S7ServedMap:
    """The S7-200 SMART Modbus slave map ``modbus_map`` (its HoldStart and MaxHold), for the one server."""

    functions = frozenset({1, 2, 3, 4, 5, 6, 15, 16})

    def __init__(self, modbus_map: S7ModbusMap) -> None:
        self.modbus_map = modbus_map
        self.tables = Tables(coils=((0, BITS),), discrete=((0, BITS),), holding=((0, modbus_map.max_hold),),
                             inputs=((0, INPUT_REGISTERS),))

    def request(self, function_code: int, start_address: int, address: int, count: int, registers: list[int],
                set_values: Values) -> Request | ExcCodes | None:
        if function_code in _BIT_FCS:
            return _bits(_BIT_FCS[function_code], start_address, address, count, registers, set_values)
        if function_code in _REGISTER_FCS:
            return _holding(self.modbus_map, start_address, address, count, registers, set_values)
        if function_code == 4:
            return None  # AIW: zeros from the staging table
        return ExcCodes.ILLEGAL_FUNCTION


def build_s7_device(emulator: S7Emulator, unit: int, modbus_map: S7ModbusMap) -> SimDevice:
    return build_device(emulator, S7ServedMap(modbus_map), unit)


def _bits(area: str, start_address: int, address: int, count: int, registers: list[int],
          set_values: Values) -> Request:
    if set_values is not None:
        values = [1 if v else 0 for v in set_values]

        def write(mem: S7Memory) -> Callable[[], None]:
            bank = mem.areas[area]
            for n, v in enumerate(values, address):
                bank[n // 8] = bank[n // 8] | 1 << n % 8 if v else bank[n // 8] & ~(1 << n % 8)
            return nothing
        return write
    first_reg = address // 16  # pymodbus hands bit tables to the action as packed 16-bit registers
    offset = first_reg - start_address

    def read(mem: S7Memory) -> Callable[[], None]:
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
             set_values: Values) -> Request:
    first_byte = modbus_map.v_byte(address)
    if set_values is not None:
        data = from_words([int(v) for v in set_values])

        def write(mem: S7Memory) -> Callable[[], None]:
            mem.write_bytes("V", first_byte, data)
            return nothing
        return write
    offset = address - start_address

    def read(mem: S7Memory) -> Callable[[], None]:
        words = to_words(mem.read_bytes("V", first_byte, 2 * count))

        def fill() -> None:
            registers[offset:offset + count] = words
        return fill
    return read


def start_s7_modbus_tcp(emulator: S7Emulator, modbus_map: S7ModbusMap, host: str = "127.0.0.1", port: int = 0,
                        unit: int = 1, *, faults: WireFaults | None = None) -> ServerHandle:
    """Serve ``emulator`` as Modbus/TCP unit ``unit`` with the S7-200 SMART map; port 0 picks a free port;
    ``faults``: the wire-fault plan every reply goes through."""
    return start_tcp(emulator, S7ServedMap(modbus_map), host, port, unit, faults=faults, kind="s7-modbus-tcp")
