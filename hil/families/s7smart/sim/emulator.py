"""An S7-200 SMART in software, on the shared scan engine: byte memory (V, I, Q, SM; memory.py) in the CPU's
engine (cpu.py), the CPU's clock with READ_RTC / SET_RTC / SET_RTC_I, and the bench's clock test program
(triggers, buffers and results in V memory) — fitted here as the profile says.

The instructions' semantics live in :class:`S7Clock` (clock.py: one method each, so a test can break one); the
test program (:class:`RtcTestProgram`, clock.py too) only decides *when* they run — on rising edges of its trigger
bits — and where the results land, as configured by the profile's ``[s7rtc]``.
"""

from __future__ import annotations

import datetime as dt
from typing import TYPE_CHECKING

from hil.families.s7smart.layout import S7Settings

# the clock model (what mutation testing judges: benchmarks/mutation.py), the engine and its memory, re-exported
from hil.families.s7smart.sim.clock import RtcTestProgram, S7Clock
from hil.families.s7smart.sim.cpu import S7Emulator
from hil.families.s7smart.sim.memory import S7Memory

if TYPE_CHECKING:
    from hil.bench.profile import Profile


def build_s7_emulator(profile: Profile, epoch: dt.datetime) -> S7Emulator:
    """The emulator an S7 profile describes: CPU (with or without RTC), clock start, and the [s7rtc] program."""
    settings: S7Settings = profile.sections["s7"]
    emulator = S7Emulator(scan_time=profile.emulator.scan_time_ms / 1000, station=profile.station,
                          seed=profile.emulator.seed, cpu=settings.cpu)
    start = epoch if settings.start == "host" else None
    emulator.add_model(S7Clock(has_rtc=settings.has_rtc, start=start))
    if "s7rtc" in profile.sections:
        emulator.add_model(RtcTestProgram(profile.sections["s7rtc"]))
    return emulator


__all__ = ["RtcTestProgram", "S7Clock", "S7Emulator", "S7Memory", "build_s7_emulator"]
