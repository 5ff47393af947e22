"""Serve the emulator over Modbus (TCP, and RTU on a pty): the FBs address map for the one engine-over-Modbus
server (:mod:`hil.sim.modbus_engine`).

The map's tables cover exactly the default FBs map (:mod:`hil.families.fbs.protocol.modbus_map`): coils Y, X, M,
S, T, C and holding registers R, D, RT, RC, DRC (two registers each); the FBs answers only 01/03/05/06/15/16 (it
has no discrete inputs or input registers: X are coils).  Everything a server does beyond the map — requests at
scan boundaries, the request gate (exceptions 1, 2, 3, unit ids, RTU broadcast), in-order TCP, strict quantities,
wire faults, ``emulator.stats`` ``modbus_*`` counters — is the one server's.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

from pymodbus.constants import ExcCodes
from pymodbus.simulator import SimDevice

from hil.families.fbs.address import WORD_BANKS as _WORD_BANKS
from hil.families.fbs.address import Address
from hil.families.fbs.protocol.modbus_map import COIL, HOLDING, segments
from hil.families.fbs.protocol.modbus_map import locate as _locate_uncached
from hil.families.fbs.sim.memory import Memory
from hil.families.fbs.sim.plc import Emulator
from hil.sim.modbus_engine import Request, Tables, Values, nothing, start_rtu_pty, start_tcp
from hil.sim.modbus_engine import build_device as build_engine_device
from hil.sim.pacing import LineRate
from hil.sim.runtime import ServerHandle
from hil.sim.wire_faults import WireFaults

#: (table, pdu) → (element, part): the map is fixed, and a walk of its segments per unit was a fifth of the cost
#: of a request.  Addresses are immutable, so sharing them is safe.
locate = functools.lru_cache(maxsize=1 << 16)(_locate_uncached)

_COIL_FCS = frozenset({1, 5, 15})
_HOLDING_FCS = frozenset({3, 6, 16})


def _ranges(table: str) -> tuple[tuple[int, int], ...]:
    """The map's segments of ``table`` as PDU ranges, adjacent ones joined."""
    out: list[tuple[int, int]] = []
    for s in segments(table):
        if out and out[-1][1] == s.pdu:
            out[-1] = (out[-1][0], s.pdu_end)
        else:
            out.append((s.pdu, s.pdu_end))
    return tuple(out)


class FbsModbusMap:
    """The default FBs Modbus map, for the one server."""

    tables = Tables(coils=_ranges(COIL), holding=_ranges(HOLDING))
    functions = _COIL_FCS | _HOLDING_FCS

    def request(self, function_code: int, start_address: int, address: int, count: int, registers: list[int],
                set_values: Values) -> Request | ExcCodes:
        if function_code in _COIL_FCS:
            return _coil_request(start_address, address, count, registers, set_values)
        if function_code in _HOLDING_FCS:
            return _holding_request(start_address, address, count, registers, set_values)
        return ExcCodes.ILLEGAL_FUNCTION


FBS_MAP = FbsModbusMap()


def build_device(emulator: Emulator, unit: int) -> SimDevice:
    """A SimDevice whose coil and holding tables cover exactly the default FBs map, backed by ``emulator``."""
    return build_engine_device(emulator, FBS_MAP, unit)


@functools.lru_cache(maxsize=1 << 12)
def _coil_slots(first_reg: int, count: int) -> tuple[tuple[int, int, str, int], ...]:
    """(register, bit, kind, index) of every mapped coil in ``count`` packed registers from ``first_reg``."""
    slots = ((r, b, locate(COIL, (first_reg + r) * 16 + b)) for r in range(count) for b in range(16))
    return tuple((r, b, found[0].kind, found[0].index) for r, b, found in slots if found is not None)


@functools.lru_cache(maxsize=1 << 12)
def _holding_slots(address: int, n: int) -> tuple[tuple[str, int, int | None], ...]:
    """(kind, index, part) of each of ``n`` registers from ``address``; part is None for a 16-bit element, 0/1 for
    the low/high word of a DRC; kind "" for a hole (the gate refuses those; stay safe regardless)."""
    slots: list[tuple[str, int, int | None]] = []
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
                  set_values: list[int] | list[bool] | None) -> Request:
    """For coils pymodbus passes ``count`` packed 16-bit registers covering the request, from bit ``address``."""
    if set_values is not None:
        targets = [locate(COIL, address + i) for i in range(len(set_values))]
        values = [1 if v else 0 for v in set_values]

        def write(mem: Memory) -> Callable[[], None]:
            for found, value in zip(targets, values):
                if found is not None:  # the gate refused unmapped coils; stay safe regardless
                    mem.bits[found[0].kind][found[0].index] = value
            return nothing
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


def _holding_request(start_address: int, address: int, count: int, registers: list[int],
                     set_values: list[int] | list[bool] | None) -> Request:
    n = len(set_values) if set_values is not None else count
    slots = _holding_slots(address, n)
    if set_values is not None:
        values = [int(v) & 0xFFFF for v in set_values]

        def write(mem: Memory) -> Callable[[], None]:
            for (kind, index, part), value in zip(slots, values):
                if kind:
                    _set_register(mem, kind, index, part, value)
            return nothing
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


# -- servers -------------------------------------------------------------------------------------------------------
def start_modbus_tcp(emulator: Emulator, host: str = "127.0.0.1", port: int = 0, unit: int = 1, *,
                     faults: WireFaults | None = None) -> ServerHandle:
    """Serve ``emulator`` as Modbus/TCP unit ``unit``; port 0 picks a free port (the handle's address has it);
    ``faults``: the wire-fault plan every reply goes through."""
    return start_tcp(emulator, FBS_MAP, host, port, unit, faults=faults)


def start_modbus_rtu_pty(emulator: Emulator, unit: int = 1, *, faults: WireFaults | None = None,
                         line: LineRate | None = None) -> ServerHandle:
    """Serve ``emulator`` as Modbus RTU unit ``unit`` on a pty; the handle's address is the path a client opens;
    ``line``: the pace of every character, both ways (None: as fast as the pty copies)."""
    return start_rtu_pty(emulator, FBS_MAP, unit, faults=faults, line=line)


__all__ = ["FBS_MAP", "FbsModbusMap", "build_device", "start_modbus_rtu_pty", "start_modbus_tcp"]
