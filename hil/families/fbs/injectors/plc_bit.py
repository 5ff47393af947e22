"""A bit on the PLC itself switches the fault (a relay in the sensor line), written through the bench's guard."""

from __future__ import annotations

from typing import Any

from hil.families.fbs.address import parse
from hil.families.fbs.injectors.injector import SensorBreakInjector


class PlcBitSensorBreak(SensorBreakInjector):
    """A bit on the PLC itself (e.g. Y40 + point drives a relay in the sensor line), through the bench's guard."""

    kind = "plc-bit"

    def __init__(self, io: Any, first: str) -> None:  # io: the bench's GuardedTransport
        super().__init__()
        self.io = io
        self.first = parse(first)

    def bit(self, point: int) -> str:
        return str(self.first.offset(point))

    def openable(self, points: list[int]) -> list[int]:
        """The points whose bit the bench's [safety] writable list lets the harness switch."""
        writable = getattr(self.io, "writable", None)
        return [p for p in points if writable is None or self.first.offset(p) in writable]

    def _set(self, point: int, open_circuit: bool) -> None:
        self.io.write(self.bit(point), 1 if open_circuit else 0)
