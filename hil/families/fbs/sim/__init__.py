"""The bundled FBs emulator: memory, scan engine, clock, models, and servers for every wire."""

from hil.families.fbs.sim.memory import Memory
from hil.families.fbs.sim.plc import Emulator
from hil.sim.model import Model

__all__ = ["Emulator", "Memory", "Model"]
