"""What every fault injector is: it puts a fault on a temperature point and takes it off again, and remembers
what it did so that the bench can undo it when a test ends."""

from __future__ import annotations

from abc import ABC, abstractmethod

from hil.core.errors import HilError, InvalidValue
from hil.families.fbs.registers import MAX_POINTS


class FaultError(HilError):
    """A fault could not be injected or undone."""


class SensorBreakInjector(ABC):
    """Opens and closes sensor circuits; remembers what it opened so that :meth:`undo` can close it."""

    kind = ""

    def __init__(self) -> None:
        self.opened: set[int] = set()

    def inject(self, point: int) -> None:
        """Put the fault on ``point`` (for a sensor break: open its circuit)."""
        self.open(point)

    def clear(self, point: int) -> None:
        """Take the fault off ``point`` again."""
        self.repair(point)

    def open(self, point: int) -> None:
        """Open ``point``'s sensor circuit (the PLC sees it at the point's next measurement)."""
        self._check(point)
        self.opened.add(point)  # before the attempt: a half-done open must still be undone
        self._set(point, True)

    def repair(self, point: int) -> None:
        """Close ``point``'s sensor circuit again."""
        self._check(point)
        self._set(point, False)
        self.opened.discard(point)

    def undo(self) -> None:
        """Close every circuit this injector opened (the bench calls this when a test ends)."""
        errors = []
        for point in sorted(self.opened):
            try:
                self.repair(point)
            except Exception as exc:  # noqa: BLE001 - try every point, then report them all
                errors.append(f"point {point}: {exc}")
        if errors:
            raise FaultError(f"{self.kind} sensor-break injector could not repair: {'; '.join(errors)}")

    def close(self) -> None:  # noqa: B027 - a hook, not abstract: most injectors hold nothing to release
        """Release what the injector holds (a rig's wire) when the bench closes."""

    def openable(self, points: list[int]) -> list[int]:
        """Which of ``points`` this injector can open (all of them, unless a rig's allow-list or a person's hands
        say fewer)."""
        return list(points)

    @staticmethod
    def _check(point: int) -> None:
        if not isinstance(point, int) or not 0 <= point < MAX_POINTS:
            raise InvalidValue(f"temperature point {point!r} is outside 0–{MAX_POINTS - 1}")

    @abstractmethod
    def _set(self, point: int, open_circuit: bool) -> None: ...
