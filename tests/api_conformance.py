"""Type-checked only (``tests/test_public_api.py`` runs mypy over it; never imported): the concrete classes a
bench builds satisfy the Protocols of the public API, so ``hil.api`` cannot drift from what a test gets."""

from __future__ import annotations

from hil.bench.faces import FaultInjector
from hil.families.fbs.device.pid import Pid as PidImpl
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.device.rtc import Rtc as RtcImpl
from hil.families.fbs.device.temperature import Temperature as TemperatureImpl
from hil.families.fbs.faces import FbsIO, Pid, Rtc, Temperature
from hil.families.fbs.injectors.injector import SensorBreakInjector
from hil.families.fbs.transport.guard import GuardedTransport


def rtc(area: RtcImpl) -> Rtc:
    return area


def pid(area: PidImpl) -> Pid:
    return area


def temperature(area: TemperatureImpl) -> Temperature:
    return area


def io(guard: GuardedTransport) -> FbsIO:
    return guard


def injector(one: SensorBreakInjector) -> FaultInjector:
    return one


def areas(plc: FbsPlc) -> tuple[Rtc, Pid, Temperature]:
    return plc.rtc, plc.pid, plc.temperature
