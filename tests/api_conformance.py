"""Type-checked only (``tests/test_public_api.py`` runs mypy over it; never imported): what a bench builds satisfies
the Protocols of the public API where the class does not declare it.  The areas (rtc, pid, temperature) subclass
their faces, so mypy checks them where they are defined; the guarded I/O, an injector and the PLC's areas as it
holds them are checked here."""

from __future__ import annotations

from hil.bench.faces import FaultInjector
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.faces import FbsIO, Pid, Rtc, Temperature
from hil.families.fbs.injectors.injector import SensorBreakInjector
from hil.families.fbs.transport.guard import GuardedTransport


def io(guard: GuardedTransport) -> FbsIO:
    return guard


def injector(one: SensorBreakInjector) -> FaultInjector:
    return one


def areas(plc: FbsPlc) -> tuple[Rtc, Pid, Temperature]:
    return plc.rtc, plc.pid, plc.temperature
