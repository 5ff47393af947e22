"""Transports: one abstraction over the FATEK protocol (serial, TCP), Modbus (RTU, TCP) and the in-process emulator.

``open_transport(url)`` (in :mod:`hil.families.fbs.transport.factory`) is the only way to get one.
"""

from hil.families.fbs.transport.base import Limits, PlcStatus, Transport

__all__ = ["Limits", "PlcStatus", "Transport"]
