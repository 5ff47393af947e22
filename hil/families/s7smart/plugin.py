"""The Siemens S7-200 SMART family, as registered under the ``hil.families`` entry-point group (``s7-200smart``)."""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable
from typing import Any

from hil.bench.family import check_wire
from hil.bench.schema import Section
from hil.core.errors import ProfileError
from hil.families.s7smart import wires as registered  # noqa: F401 - registers the family's schemes and wires (hil.core.registry)
from hil.families.s7smart.address import expand_s7
from hil.families.s7smart.bench import S7Bench
from hil.families.s7smart.layout import S7, S7RTC, check_s7_ranges, parse_s7_settings, parse_s7rtc
from hil.families.s7smart.protocol.modbus_map import S7ModbusMap
from hil.families.s7smart.sim.emulator import build_s7_emulator
from hil.families.s7smart.sim.serve_modbus import start_s7_modbus_tcp
from hil.families.s7smart.sim.serve_s7 import start_s7_server


class S7SmartFamily:
    name = "s7-200smart"
    title = "S7-200 SMART"
    a_title = "an S7-200 SMART"
    default = False
    sections: tuple[str, ...] = ("s7", "s7rtc")
    declarations: tuple[Section, ...] = (S7, S7RTC)
    default_volatile: tuple[str, ...] = ()  # S7 operand names (VB100-VB139); no read-out the CPU rewrites on its own

    def check_ranges(self, ranges: list) -> bool:
        return check_s7_ranges(ranges)

    def elements(self, ranges: Iterable[str]) -> frozenset:
        return expand_s7(ranges)

    def parse_sections(self, tables: dict[str, dict[str, Any]], where: str) -> dict[str, Any]:
        out: dict[str, Any] = {"s7": parse_s7_settings(tables.get("s7", {}), where)}  # [s7] has defaults
        if "s7rtc" in tables:
            out["s7rtc"] = parse_s7rtc(tables["s7rtc"], where)
        return out

    def check_faults(self, faults: dict[str, dict[str, Any]], where: str) -> None:
        if faults:
            raise ProfileError(f"{where}: an S7-200 SMART bench has no fault injectors; remove "
                               f"{', '.join(f'[faults.{name}]' for name in faults)}")

    def build_emulator(self, profile: Any, epoch: dt.datetime) -> Any:
        return build_s7_emulator(profile, epoch)

    def open_bench(self, profile: Any, **kwargs: Any) -> Any:
        return S7Bench(profile, **kwargs)

    wires: tuple[str, ...] = ("s7-tcp", "modbus-tcp")

    def serve(self, profile: Any, emulator: Any, wire: str, host: str, port: int) -> Any:
        check_wire(self, wire)
        if wire == "s7-tcp":
            return start_s7_server(emulator, host, port)
        settings = profile.sections["s7"]
        return start_s7_modbus_tcp(emulator, S7ModbusMap(settings.hold_start, settings.max_hold), host, port,
                                   unit=profile.station)


FAMILY = S7SmartFamily()
