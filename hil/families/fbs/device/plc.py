"""FbsPlc: the facade suites use through the bench fixture (``bench.plc``)."""

from __future__ import annotations

from hil.core.timebase import Timebase
from hil.families.fbs.transport.base import PlcStatus, Transport


class FbsPlc:
    """One FBs PLC reached through ``transport`` (normally the guarded transport of the bench).

    ``plc.io`` is the raw transport for suites that must do a procedure step by step; ``plc.time`` is the
    bench's timebase.  Areas (``plc.rtc`` …) are attached by their own modules.
    """

    def __init__(self, transport: Transport, timebase: Timebase, *, settle_scans: int = 2) -> None:
        self.io = transport
        self.time = timebase
        self.settle_scans = settle_scans
        from hil.families.fbs.device.rtc import Rtc  # noqa: PLC0415 - areas import FbsPlc's module for typing
        self.rtc = Rtc(self)
        from hil.families.fbs.device.temperature import Temperature  # noqa: PLC0415
        self.temperature = Temperature(self)  # configured by the bench from the profile's [temperature]
        from hil.families.fbs.device.pid import Pid  # noqa: PLC0415
        self.pid = Pid(self)  # configured by the bench from the profile's [pid]

    def status(self) -> PlcStatus:
        return self.io.status()

    def settle(self, scans: int | None = None) -> None:
        """Make sure the PLC has completed whole scans since our last write.

        Port 0 answers at the end of a scan, so each round trip spans at least one scan: a few cheap status
        requests settle a real PLC and the emulator alike, with no guessing at scan times.
        """
        for _ in range(self.settle_scans if scans is None else scans):
            self.io.status()

    def settle_before_request(self) -> None:
        """Settle when the procedure's next step is itself a request (a read of the effect, the next write).

        That request is serviced at the end of a scan after the write too, so it counts as one of the
        ``settle_scans``: one status round trip fewer, the same scans before the effect is looked at."""
        self.settle(max(0, self.settle_scans - 1))
