"""What a test sees of an S7-200 SMART bench, as Protocols: the proxy of the bench and of its I/O is built from
them (:mod:`hil.bench.view`)."""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

from hil.bench.faces import BenchView, PlcIO

if TYPE_CHECKING:
    from hil.families.s7smart.layout import S7Settings


class S7IO(PlcIO, Protocol):
    """An S7-200 SMART's operands (``bench.plc.io``): ``VB``/``VW``/``VD`` bytes and words, ``V10.3``, ``Q0.0``,
    ``I0.0`` bits.  Writes go through the guard (bytes and bits are its elements)."""

    def read_v(self, first: int, count: int) -> bytes:
        """``count`` V bytes from VB``first``."""
        ...

    def write_v(self, first: int, data: bytes | Sequence[int]) -> None:
        """V bytes from VB``first``, through the guard."""
        ...

    def read_bits(self, name: Any, count: int = 1) -> list[int]:
        """``count`` consecutive bits from ``name``."""
        ...

    def status(self) -> Any:
        """RUN/STOP as the wire can tell."""
        ...

    @property
    def has_cpu_clock(self) -> bool:
        """True when the wire has clock functions (the S7 protocol; not Modbus)."""
        ...

    def cpu_clock(self) -> dt.datetime:
        """The CPU's clock read with the protocol's function."""
        ...

    def set_cpu_clock(self, when: dt.datetime) -> None:
        """Set the CPU's clock with the protocol's function (journaled first, restored at its offset)."""
        ...


class S7Bench(BenchView, Protocol):
    """The ``bench`` fixture on an S7-200 SMART bench."""

    @property
    def settings(self) -> S7Settings:
        """The profile's ``[s7]`` (CPU, the Modbus map's HoldStart/MaxHold)."""
        ...

    def power_cycle(self, *, backup_expired: bool = False) -> None:
        """Emulator only: switch the CPU off and on (``backup_expired``: the clock's back-up ran out)."""
        ...


__all__ = ["S7Bench", "S7IO"]
