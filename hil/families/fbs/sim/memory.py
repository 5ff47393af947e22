"""The emulator's element memory, sized like an FBs main unit, with access by
:class:`~hil.families.fbs.address.Address`.

Models reach the banks directly (``mem.words["R"][4128]``, ``mem.bits["M"][1952]``) for speed; requests —
from a wire server or from the in-process transport alike — go through :meth:`Memory.read` / :meth:`Memory.write`
/ :meth:`Memory.get` / :meth:`Memory.set`, which understand every element kind and refuse what an FBs does not have
(:class:`Refused`), so the emulator answers the same whoever asks.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence, Sized

from hil.core.errors import PlcErrorReply
from hil.families.fbs.address import (
    BIT_BANKS,
    COUNTER32_FIRST,
    LOW_WORD_FIRST,
    PACKED_16,
    PACKED_32,
    PAIRED_32,
    WORD_BANKS,
    Address,
    missing,
    parse,
)

_COUNTER32_COUNT = 256 - COUNTER32_FIRST


class Refused(PlcErrorReply):
    """A request the emulated PLC refuses as an FBs does: error A for elements it does not have (R4168–R4999).
    The FATEK server answers with :attr:`code`; in process the caller sees this error, as a FATEK client sees the
    PLC's error reply."""

    def __init__(self, reason: str) -> None:
        super().__init__("A", "illegal address", reason)


def _exists(a: Address, count: int = 1) -> Address:
    reason = missing(a, count)
    if reason is not None:
        raise Refused(reason)
    return a


class Memory:
    def __init__(self) -> None:
        self.bits: dict[str, bytearray] = {k: bytearray(n) for k, n in BIT_BANKS.items()}
        self.words: dict[str, list[int]] = {k: [0] * n for k, n in WORD_BANKS.items()}
        self.counters32: list[int] = [0] * _COUNTER32_COUNT  # C200–C255
        self.disabled: dict[str, bytearray] = {k: bytearray(n) for k, n in BIT_BANKS.items()}  # commands 42/43

    # -- single elements ------------------------------------------------------------------------------------
    def get(self, address: str | Address) -> int:
        a = _exists(parse(address))
        kind, i = a.kind, a.index
        if kind in self.bits:
            return self.bits[kind][i]
        if kind in self.words:
            return self.words[kind][i]
        if kind in PACKED_16 or kind in PACKED_32:
            bank = self.bits[PACKED_16.get(kind) or PACKED_32[kind]]
            return sum(bank[i + b] << b for b in range(a.bits))
        if kind in PAIRED_32:
            lo, hi = self.words[PAIRED_32[kind]][i], self.words[PAIRED_32[kind]][i + 1]
            return (hi << 16 | lo) if LOW_WORD_FIRST else (lo << 16 | hi)
        return self.counters32[i - COUNTER32_FIRST]  # DRC

    def set(self, address: str | Address, value: int) -> None:
        a = _exists(parse(address))
        kind, i = a.kind, a.index
        if kind in self.bits:
            self.bits[kind][i] = 1 if value else 0
        elif kind in self.words:
            self.words[kind][i] = value & 0xFFFF
        elif kind in PACKED_16 or kind in PACKED_32:
            bank = self.bits[PACKED_16.get(kind) or PACKED_32[kind]]
            for b in range(a.bits):
                bank[i + b] = value >> b & 1
        elif kind in PAIRED_32:
            lo, hi = value & 0xFFFF, value >> 16 & 0xFFFF
            words = self.words[PAIRED_32[kind]]
            words[i], words[i + 1] = (lo, hi) if LOW_WORD_FIRST else (hi, lo)
        else:
            self.counters32[i - COUNTER32_FIRST] = value & 0xFFFFFFFF

    # -- runs -------------------------------------------------------------------------------------------------
    def read(self, first: str | Address, count: int) -> list[int]:
        a = _exists(parse(first), count)
        if a.kind in self.words:  # the common case, without per-element parsing
            return self.words[a.kind][a.index:a.index + count]
        if a.kind in self.bits:
            return list(self.bits[a.kind][a.index:a.index + count])
        return [self.get(a.offset(n)) for n in range(count)]

    def write(self, first: str | Address, values: Sequence[int]) -> None:
        a = _exists(parse(first), len(values))
        if a.kind in self.words:
            self.words[a.kind][a.index:a.index + len(values)] = [v & 0xFFFF for v in values]
        elif a.kind in self.bits:
            self.bits[a.kind][a.index:a.index + len(values)] = bytes(1 if v else 0 for v in values)
        else:
            for n, v in enumerate(values):
                self.set(a.offset(n), v)

    # -- whole-memory views for tests and tools ---------------------------------------------------------------
    def banks(self) -> dict[str, Sized]:
        """Every bank by name, for the engine's check that no model changes a bank's size."""
        return {**self.bits, **self.words, f"DRC{COUNTER32_FIRST}–": self.counters32,
                **{f"{kind} (disabled)": flags for kind, flags in self.disabled.items()}}

    def snapshot(self) -> dict:
        """A deep copy of every bank; compare two snapshots to prove nothing changed."""
        return {"bits": copy.deepcopy(self.bits), "words": copy.deepcopy(self.words),
                "counters32": list(self.counters32), "disabled": copy.deepcopy(self.disabled)}

    def word(self, name: str) -> int:
        return self.get(name)
