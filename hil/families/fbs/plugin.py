"""The FATEK FBs family, as registered under the ``hil.families`` entry-point group (``fbs``)."""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable, Iterable
from typing import Any

from hil.bench.family import check_wire
from hil.bench.profile import Profile
from hil.bench.schema import Section
from hil.core.errors import InvalidValue
from hil.families.fbs import entries  # noqa: F401 - its schemes, wires, report areas and plots (registered)
from hil.families.fbs.address import expand, parse_range
from hil.families.fbs.bench import Bench
from hil.families.fbs.injectors.config import FAULTS, check_fault_configs
from hil.families.fbs.pid import PID, parse_pid
from hil.families.fbs.rtc_profile import RTC, parse_rtc
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.models.plant_config import PLANT, parse_plant
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.temperature import TEMPERATURE, parse_temperature
from hil.families.fbs.transport.base import value_problem
from hil.families.fbs.transport.factory import serve
from hil.sim.engine import Engine
from hil.sim.runtime import ServerHandle


class FbsFamily:
    name = "fbs"
    title = "FATEK FBs"
    a_title = "a FATEK FBs"
    default = True  # the harness's first family: a profile naming none, a suite without a family marker
    sections: tuple[str, ...] = ("rtc", "temperature", "pid", "plant")
    declarations: tuple[Section, ...] = (RTC, TEMPERATURE, PID, PLANT, FAULTS)
    default_volatile: tuple[str, ...] = ("R4128-R4135",)  # the RTC read-out: the PLC rewrites it every scan
    #: may be both writable and volatile: the guard's clock (Rtc.clock) restores them, not the journal
    clock_elements: tuple[str, ...] = ("R4128-R4135",)

    def check_ranges(self, ranges: list) -> bool:
        for item in ranges:
            if not isinstance(item, str):
                raise InvalidValue(f"{item!r} is not an address range like 'R4128-R4135'")
            parse_range(item)
        return True

    def elements(self, ranges: Iterable[str]) -> frozenset:
        return expand(ranges)

    def value_problem(self, element: Any, value: int) -> str | None:
        """Why ``value`` cannot be held by ``element`` (None when it can)."""
        return value_problem(element, value)

    def parse_sections(self, tables: dict[str, dict[str, Any]], where: str) -> dict[str, Any]:
        parsers: dict[str, Callable[[dict[str, Any], str], Any]] = {
            "rtc": parse_rtc, "temperature": parse_temperature, "pid": parse_pid, "plant": parse_plant}
        return {name: parsers[name](table, where) for name, table in tables.items()}

    def check_faults(self, faults: dict[str, dict[str, Any]], where: str) -> None:
        check_fault_configs(faults, where)

    def build_emulator(self, profile: Profile, epoch: dt.datetime) -> Emulator:
        return build_emulator(profile, epoch)

    def open_bench(self, profile: Profile, **kwargs: Any) -> Bench:
        return Bench(profile, **kwargs)

    wires: tuple[str, ...] = ("fatek-tcp", "fatek-udp", "fatek-serial", "modbus-tcp", "modbus-rtu")

    def serve(self, profile: Profile, emulator: Engine, wire: str, host: str, port: int) -> ServerHandle:
        check_wire(self, wire)
        if not isinstance(emulator, Emulator):  # another family's: its own plug-in serves it
            raise InvalidValue(f"{type(emulator).__name__} is not an FBs emulator: {self.title} cannot serve it")
        return serve(emulator, wire, host, port, line=profile.emulator.line)  # [emulator] line paces the ptys


FAMILY = FbsFamily()

__all__ = ["FAMILY", "FbsFamily"]
