"""What every bench does the same way, whichever controller family it serves (FBs, S7-200 SMART)."""

from __future__ import annotations

from typing import Any

from hil.bench.profile import Profile
from hil.core.timebase import Timebase


class BenchBase:
    """Subclasses set ``profile``, ``raw`` (the unguarded link, with ``.emulator``), ``time`` and ``plc``."""

    profile: Profile
    raw: Any
    time: Timebase
    plc: Any

    @property
    def name(self) -> str:
        return self.profile.name

    @property
    def is_emulator(self) -> bool:
        """True when the PLC is the in-process emulator (virtual time, direct fault injection)."""
        return self.raw.emulator is not None

    def identity(self) -> dict[str, str]:
        """What the family adds to the PLC's identity in reports (e.g. an FBs's RTC chip); never raises."""
        return {}

    def finish(self) -> None:
        """The session ends: put back exactly what was put back only approximately after each test (an FBs's
        clock phase).  Raises :class:`hil.core.errors.RestoreError` when the PLC refuses."""

    def wait(self, seconds: float) -> None:
        """Let bench time pass: sleep on a real PLC (÷ time_scale), advance virtual time on the emulator."""
        self.time.wait(seconds)

    def settle(self) -> None:
        """Make sure the PLC has completed whole scans since the last write."""
        self.plc.settle()
