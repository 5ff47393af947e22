"""An FBs main unit in software: the shared scan engine with FBs memory and what a power-on leaves in it."""

from __future__ import annotations

import os
from collections.abc import Iterable

from hil.families.fbs.address import Address
from hil.families.fbs.registers import POWER_ON_DEFAULTS
from hil.families.fbs.sim.memory import Memory
from hil.sim.engine import Engine
from hil.sim.model import Model
from hil.sim.timing import INSTANT, Timing

#: Main-unit identity the emulator reports in the detailed status (command 53). [our choice] values.
UNIT_TYPE_MC = 0x01
OS_VERSION = 0x40  # "V4.0x"


class Emulator(Engine):
    """An FBs main unit.  Thread-safe: every entry point takes :attr:`lock`."""

    family = "fbs"
    memory: Memory

    def __init__(self, *, scan_time: float = 0.01, models: Iterable[Model] = (), station: int = 1,
                 seed: int = 0, timing: Timing = INSTANT) -> None:
        super().__init__(Memory(), scan_time=scan_time, station=station, seed=seed, timing=timing)
        # [our choice] each emulator is a PLC of its own: a serial of its own, served in its identity (command
        # 53), so that a journal, a lock or a rig check never takes one emulator for another
        self.serial = os.urandom(8)
        for name, value in POWER_ON_DEFAULTS.items():
            self.memory.set(name, value)
        for model in models:
            self.add_model(model)

    #: the bench ladder's scan counter ([bench] scan_counter, fixtures/ladder.md), when the profile declares one
    scan_counter: Address | None = None

    def end_scan(self) -> None:
        if self.scan_counter is not None:
            # the rung "R := R + 1" at the end of every scan; the spans the engine jumps over (no model
            # needed a scan, no request could look) count as the scans a PLC would have run in them
            self.memory.set(self.scan_counter, self.scans_represented & 0xFFFF)
