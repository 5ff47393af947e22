"""Models of PLC behaviour that plug into the emulator's scan engine (RTC, and later the other areas)."""

from hil.families.fbs.sim.models.rtc import RtcModel

__all__ = ["RtcModel"]
