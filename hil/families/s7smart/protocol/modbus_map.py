"""The S7-200 SMART Modbus slave map (MBUS_SLAVE library, system manual table 9-1), pure.

    00001–00256  coils             Q0.0–Q31.7      (PDU 0–255, bit n = Q(n // 8).(n % 8))
    10001–10256  discrete inputs   I0.0–I31.7
    30001–30056  input registers   AIW0–AIW110
    40001…       holding registers VW(HoldStart), VW(HoldStart + 2), … (MaxHold registers)

V words are big-endian: register k carries VB(HoldStart + 2k) in its high byte.  A V byte outside
HoldStart … HoldStart + 2·MaxHold − 1 cannot be reached over Modbus: that is an error naming both.
"""

from __future__ import annotations

from dataclasses import dataclass

from hil.core.errors import InvalidValue, UnreachableAddress
from hil.families.s7smart.address import S7Address

BITS = 256  # Q0.0–Q31.7 and I0.0–I31.7
INPUT_REGISTERS = 56  # AIW0–AIW110
MAX_READ_REGISTERS, MAX_WRITE_REGISTERS = 125, 123
MAX_READ_BITS, MAX_WRITE_BITS = 2000, 1968


@dataclass(frozen=True)
class S7ModbusMap:
    hold_start: int = 0  # V byte of 40001
    max_hold: int = 1000

    @property
    def v_end(self) -> int:
        return self.hold_start + 2 * self.max_hold

    def registers_for(self, first: int, count: int) -> tuple[int, int]:
        """(first PDU register, register count) covering V bytes ``first`` … ``first + count − 1``."""
        if count < 1:
            raise InvalidValue("count must be ≥ 1")
        if first < self.hold_start or first + count > self.v_end:
            raise UnreachableAddress(
                f"VB{first}" + (f"–VB{first + count - 1}" if count > 1 else ""), "Modbus (S7-200 SMART map)",
                f"holding registers reach VB{self.hold_start}–VB{self.v_end - 1} (HoldStart VB{self.hold_start}, "
                f"MaxHold {self.max_hold}); move the buffer or widen [s7] max_hold")
        lo = (first - self.hold_start) // 2
        hi = (first + count - 1 - self.hold_start) // 2
        return lo, hi - lo + 1

    def v_byte(self, register: int) -> int:
        """The V byte in the high half of PDU holding register ``register``."""
        return self.hold_start + 2 * register

    @staticmethod
    def bit_number(address: S7Address) -> int:
        """PDU coil (Q) or discrete input (I) number of a bit operand."""
        if not address.is_bit or address.area not in ("Q", "I"):
            raise InvalidValue(f"{address} is not a Q or I bit")
        n = address.byte * 8 + address.bit_in_byte
        if n >= BITS:
            raise UnreachableAddress(str(address), "Modbus (S7-200 SMART map)", "only Q0.0–Q31.7 and I0.0–I31.7 "
                                     "are mapped")
        return n


def to_words(data: bytes) -> list[int]:
    return [data[i] << 8 | data[i + 1] for i in range(0, len(data), 2)]


def from_words(words: list[int]) -> bytes:
    return b"".join(int(w & 0xFFFF).to_bytes(2, "big") for w in words)
