"""The S7-200 SMART's memory in the emulator: byte-addressed areas (V, I, Q, M, SM …) — below the clock models
that read and write it (clock.py) and the engine that holds it (cpu.py)."""

from __future__ import annotations

import copy
from collections.abc import Sized

from hil.families.s7smart.address import AREA_BYTES, S7Address, parse_s7


class S7Memory:
    """Byte-addressed areas; bits are ``byte.bit`` (bit 0 = least significant), words big-endian."""

    def __init__(self) -> None:
        self.areas: dict[str, bytearray] = {a: bytearray(n) for a, n in AREA_BYTES.items()}

    def banks(self) -> dict[str, Sized]:
        """Every area by name, for the engine's check that no model changes an area's size."""
        return dict(self.areas)

    @property
    def v(self) -> bytearray:
        return self.areas["V"]

    def read_bytes(self, area: str, first: int, count: int) -> bytes:
        return bytes(self.areas[area][first:first + count])

    def write_bytes(self, area: str, first: int, data: bytes) -> None:
        bank = self.areas[area]
        if first < 0 or first + len(data) > len(bank):
            raise IndexError(f"{area}B{first}…+{len(data)} is outside {area} memory")
        bank[first:first + len(data)] = data

    def get(self, name: str | S7Address) -> int:
        a = parse_s7(name)
        bank = self.areas[a.area]
        if a.is_bit:
            return bank[a.byte] >> a.bit_in_byte & 1
        return int.from_bytes(bank[a.byte:a.end], "big")

    def set(self, name: str | S7Address, value: int) -> None:
        a = parse_s7(name)
        bank = self.areas[a.area]
        if a.is_bit:
            mask = 1 << a.bit_in_byte
            bank[a.byte] = bank[a.byte] | mask if value else bank[a.byte] & ~mask
        else:
            bank[a.byte:a.end] = (int(value) & ((1 << 8 * a.size) - 1)).to_bytes(a.size, "big")

    def snapshot(self) -> dict[str, bytearray]:
        return copy.deepcopy(self.areas)


__all__ = ["S7Memory"]
