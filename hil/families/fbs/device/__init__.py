"""The PLC as a test sees it: procedures (set the clock, measure drift, read temperatures), not register math."""

from hil.families.fbs.device.plc import FbsPlc

__all__ = ["FbsPlc"]
