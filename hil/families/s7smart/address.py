"""S7-200 SMART operand names: ``VB110``, ``VW104``, ``VD200``, ``V100.0``, ``I0.3``, ``Q1.7``, ``IB0``, ``SM4.3``.

Kept apart from :mod:`hil.families.fbs.address` (FBs element names): the S7 addresses bytes, with bits as ``byte.bit``
and words/double words as big-endian runs of bytes starting at the named byte (VW100 = VB100 high, VB101 low).
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass

from hil.core.errors import AddressError

#: Bytes per area [our choice for the emulator: V as an ST60 (20 KB), I/Q as the 32 bytes Modbus maps].
AREA_BYTES = {"V": 20480, "I": 32, "Q": 32, "SM": 1536}
_SIZES = {"B": 1, "W": 2, "D": 4}
_NAME = re.compile(r"^(SM|V|I|Q)(?:(B|W|D)(\d+)|(\d+)\.([0-7]))$")


@dataclass(frozen=True, order=True)
class S7Address:
    area: str  # "V", "I", "Q", "SM"
    byte: int
    bit: int | None = None  # 0–7 for a bit operand
    size: int = 1  # bytes for B/W/D; 1 for a bit

    @property
    def is_bit(self) -> bool:
        return self.bit is not None

    @property
    def bit_in_byte(self) -> int:
        """A bit operand's bit, 0–7 (AddressError for a byte, word or double word)."""
        if self.bit is None:
            raise AddressError(f"{self} is not a bit operand")
        return self.bit

    @property
    def end(self) -> int:
        """First byte after this operand."""
        return self.byte + self.size

    def __str__(self) -> str:
        if self.is_bit:
            return f"{self.area}{self.byte}.{self.bit}"
        return f"{self.area}{'BWD'[(1, 2, 4).index(self.size)]}{self.byte}"


def parse_s7(name: str | S7Address) -> S7Address:
    if isinstance(name, S7Address):
        return name
    text = str(name).strip().upper()
    m = _NAME.match(text)
    if not m:
        raise AddressError(f"{name!r} is not an S7-200 SMART operand (e.g. VB110, VW104, V100.0, Q0.1, I0.0, SM4.3)")
    area, kind, byte_s, bit_byte, bit = m.groups()
    address = (S7Address(area, int(byte_s), None, _SIZES[kind]) if kind
               else S7Address(area, int(bit_byte), int(bit), 1))
    if address.end > AREA_BYTES[area]:
        raise AddressError(f"{name!r} is outside {area} memory (0–{AREA_BYTES[area] - 1})")
    return address


def parse_s7_range(text: str) -> list[S7Address]:
    """``"VB100-VB139"`` → the bytes; ``"Q0.0-Q0.7"`` → the bits; a single operand → itself."""
    first_s, sep, last_s = str(text).partition("-")
    first = parse_s7(first_s)
    if not sep:
        return [first]
    last = parse_s7(last_s)
    if (first.area, first.is_bit, first.size) != (last.area, last.is_bit, last.size):
        raise AddressError(f"range {text!r} mixes {first} and {last}")
    if first.is_bit:
        lo, hi = first.byte * 8 + first.bit_in_byte, last.byte * 8 + last.bit_in_byte
        if hi < lo:
            raise AddressError(f"range {text!r} runs backwards")
        return [S7Address(first.area, n // 8, n % 8) for n in range(lo, hi + 1)]
    if last.byte < first.byte:
        raise AddressError(f"range {text!r} runs backwards")
    return [S7Address(first.area, b, None, first.size) for b in range(first.byte, last.byte + 1, first.size)]


def units(address: S7Address) -> list[S7Address]:
    """The guard's elements: one byte per byte of a byte/word/dword (VW100 → VB100, VB101), a bit as itself."""
    if address.is_bit:
        return [address]
    return [S7Address(address.area, b) for b in range(address.byte, address.end)]


def expand_s7(ranges: Iterable[str]) -> frozenset[S7Address]:
    """The elements ``["VB100-VB101", "Q0.0-Q0.7"]`` name; a listed byte lists its eight bits too (a bit is
    writable when it is listed or its whole byte is)."""
    out: set[S7Address] = set()
    for text in ranges:
        for a in parse_s7_range(text):
            for element in units(a):
                out.add(element)
                if not element.is_bit:
                    out.update(S7Address(element.area, element.byte, bit) for bit in range(8))
    return frozenset(out)
