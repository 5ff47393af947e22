"""FbsPlc: the facade suites use through the bench fixture (``bench.plc``): the PLC's core and its areas."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from hil.core.timebase import Timebase
from hil.families.fbs.device.core import PlcCore
from hil.families.fbs.device.pid import Pid
from hil.families.fbs.device.rtc import Rtc
from hil.families.fbs.device.temperature import Temperature
from hil.families.fbs.transport.base import Transport


class FbsPlc(PlcCore):
    """One FBs PLC reached through ``transport`` (normally the guarded transport of the bench).

    ``plc.io`` is the raw transport for suites that must do a procedure step by step; ``plc.time`` is the
    bench's timebase; ``plc.rtc``, ``plc.temperature`` and ``plc.pid`` are its areas.
    """

    def __init__(self, transport: Transport, timebase: Timebase, *, settle_scans: int = 2,
                 scan_counter: str | None = None, answers_at_scan_end: bool = False) -> None:
        super().__init__(transport, timebase, settle_scans=settle_scans, scan_counter=scan_counter,
                         answers_at_scan_end=answers_at_scan_end)
        self.rtc = Rtc(self)
        self.temperature = Temperature(self)  # configured by the bench from the profile's [temperature]
        self.pid = Pid(self, self.temperature)  # configured by the bench from the profile's [pid]

    def configure(self, sections: Mapping[str, Any]) -> None:
        """The areas a profile describes (its parsed ``[temperature]`` and ``[pid]`` sections) — for the bench a
        suite holds and for recovery, which must know what FUN86 rewrites as the run's bench knew it."""
        if "temperature" in sections:
            self.temperature.config = sections["temperature"]
        if "pid" in sections:
            self.pid.config = sections["pid"]


__all__ = ["FbsPlc"]
