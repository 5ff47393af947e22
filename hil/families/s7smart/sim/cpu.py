"""The S7-200 SMART's CPU in the emulator: the shared scan engine with S7 memory, and its power cycle — below the
models that run in it (clock.py) and the builder that fits them (emulator.py)."""

from __future__ import annotations

from collections.abc import Iterable

from hil.families.s7smart.sim.memory import S7Memory
from hil.sim.engine import Engine
from hil.sim.model import Model


class S7Emulator(Engine):
    """The shared scan engine (service at a scan boundary, virtual time) with S7 memory instead of FBs memory."""

    family = "s7-200smart"

    def __init__(self, *, scan_time: float = 0.01, models: Iterable[Model[S7Emulator]] = (), station: int = 1,
                 seed: int = 0,
                 cpu: str = "ST40") -> None:
        super().__init__(S7Memory(), scan_time=scan_time, station=station, seed=seed)
        self.cpu = cpu
        self.version = f"{Engine.version} (S7-200 SMART {cpu})"
        for model in models:
            self.add_model(model)

    def power_cycle(self, *, backup_expired: bool = False) -> None:
        """Power off and on: the clock keeps time only while its back-up lasts (and never on a CR40/CR60);
        programs start again from their first scan."""
        with self.lock:
            for model in self.models:
                cycle = getattr(model, "power_cycle", None)
                if cycle is not None:
                    cycle(self, backup_expired=backup_expired)
                else:
                    model.power_on(self)


__all__ = ["S7Emulator"]
