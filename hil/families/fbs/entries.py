"""What the FBs family registers (:mod:`hil.core.registry`), without its device layer or emulator: the
``hil.registers`` entry point, imported on the first look-up of a registry."""

from hil.families.fbs import report, wires

__all__ = ["report", "wires"]
