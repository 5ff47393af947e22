"""What the temperature procedures return (``plc.temperature``): the table and the work block as read — values,
below both the faces (:mod:`hil.families.fbs.faces`) and the device layer that reads them
(:mod:`hil.families.fbs.device.temperature`)."""

from __future__ import annotations

from dataclasses import dataclass

from hil.families.fbs import registers as reg

#: the work block's break words, TW+1 (points 0–15) and TW+2 (points 16–31): their offset from TW
BREAK_WORDS_AT = 1


@dataclass(frozen=True)
class TableView:
    """SR+0 … SR+3+N as read from the PLC."""

    words: list[int]

    @property
    def marker(self) -> int:
        return self.words[0]

    @property
    def module_count(self) -> int:
        return self.words[1]

    @property
    def modules(self) -> list[tuple[int, int]]:
        """(sensor-kind code, module-name code) per module entry."""
        return [(w >> 8, w & 0xFF) for w in self.words[4:]]


@dataclass(frozen=True)
class WorkView:
    """TW+0 … TW+3+4N as read from the PLC."""

    words: list[int]

    @property
    def execution_code(self) -> int:
        return self.words[0] >> 8

    @property
    def mismatch_bits(self) -> int:
        return self.words[0] & 0xFF

    @property
    def break_words(self) -> tuple[int, int]:
        """(TW+1, TW+2): break bits of points 0–15 and 16–31."""
        return self.words[BREAK_WORDS_AT], self.words[BREAK_WORDS_AT + 1]

    @property
    def break_points(self) -> list[int]:
        low, high = self.break_words
        bits = high << 16 | low
        return [p for p in range(reg.MAX_POINTS) if bits >> p & 1]

    @property
    def total_points(self) -> int:
        return self.words[3] >> 8

    @property
    def module_count(self) -> int:
        return self.words[3] & 0xFF

    def entry(self, k: int) -> list[int]:
        """The four words of module k (0-based): sensor/DO, points/AI, readings start, multiplexer index."""
        return self.words[4 + 4 * k:8 + 4 * k]


__all__ = ["TableView", "WorkView"]
