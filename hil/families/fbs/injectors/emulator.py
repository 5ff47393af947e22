"""Faults put straight into the in-process emulator: a sensor break in its temperature model, a heater fault in
its thermal plant."""

from __future__ import annotations

from typing import Any

from hil.families.fbs.injectors.injector import SensorBreakInjector


class EmulatorSensorBreak(SensorBreakInjector):
    kind = "emulator"

    def __init__(self, emulator: Any, model: Any) -> None:  # an Emulator and its TemperatureModel
        super().__init__()
        self.emulator = emulator
        self.model = model

    def _set(self, point: int, open_circuit: bool) -> None:
        with self.emulator.lock:  # the emulator may be serving a wire from another thread
            (self.model.open if open_circuit else self.model.repair)(point)


class EmulatorPlantFault(SensorBreakInjector):
    """heater_open / ssr_short inside the in-process emulator's thermal plant (seen from the next scan)."""

    kind = "emulator"

    def __init__(self, emulator: Any, plant: Any, fault: str) -> None:  # an Emulator and its ThermalPlant
        super().__init__()
        self.emulator = emulator
        self.plant = plant
        self.fault = fault

    def _set(self, point: int, on: bool) -> None:
        with self.emulator.lock:
            self.plant.set_fault(self.fault, point, on)
