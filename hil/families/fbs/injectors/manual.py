"""The operator at the bench switches the fault by hand when asked."""

from __future__ import annotations

from collections.abc import Callable

from hil.families.fbs.injectors.config import FAULT_ACTIONS
from hil.families.fbs.injectors.injector import SensorBreakInjector


class ManualSensorBreak(SensorBreakInjector):
    """Asks the operator at the bench to open or close a circuit, and waits for Enter."""

    kind = "manual"

    def __init__(self, ask: Callable[[str], str] | None = None, fault: str = "sensor_break") -> None:
        super().__init__()
        self.ask = ask or _ask_terminal
        self.fault = fault

    def openable(self, points: list[int]) -> list[int]:
        """A person opens each circuit by hand: the first and last of points 0–15 and of 16–31 (the ends of R4010/TW+1
        and of R4011/TW+2), not every point."""
        ends = []
        for half in ([p for p in points if p < 16], [p for p in points if p >= 16]):
            ends += sorted({half[0], half[-1]}) if half else []
        return ends

    def _set(self, point: int, open_circuit: bool) -> None:
        if self.fault == "sensor_break":
            action = "DISCONNECT" if open_circuit else "RECONNECT"
            self.ask(f"{action} the sensor of temperature point {point}, then press Enter: ")
            return
        action = FAULT_ACTIONS[self.fault][0 if open_circuit else 1]
        self.ask(f"{action} of temperature point {point}, then press Enter: ")


def _ask_terminal(prompt: str) -> str:
    # pytest captures stdin/stdout; the terminal itself still reaches the operator.
    try:
        with open("/dev/tty", "r+") as tty:
            tty.write("\n" + prompt)
            tty.flush()
            return tty.readline()
    except OSError:
        return input(prompt)
