"""The bundled FBs emulator: memory, scan engine, clock, models, and servers for every wire."""

from hil.emulator.core import Emulator
from hil.emulator.memory import Memory
from hil.emulator.model import Model

__all__ = ["Emulator", "Memory", "Model"]
