"""A bench: the profile made live — the PLC behind its guard, the bench's time, and the per-test restore.

The pytest plugin builds one Bench per session; suites see it as the ``bench`` fixture.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable

from hil.bench.base import BenchBase
from hil.bench.profile import Profile, plc_target
from hil.bench.view import guarded_io
from hil.core.timebase import Timebase, timebase_for
from hil.families.fbs import faces
from hil.families.fbs import registers as reg
from hil.families.fbs.address import parse_range
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.faults import Faults
from hil.families.fbs.identity import read_identity
from hil.families.fbs.recovery import rig_steps, rig_targets
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.transport.base import Transport
from hil.families.fbs.transport.factory import open_transport
from hil.families.fbs.transport.fatek import UNIT_TYPES
from hil.families.fbs.transport.guard import GuardedTransport
from hil.io.url import Target
from hil.sim.wire_faults import WireFaults

EmulatorBuilder = Callable[[Profile, dt.datetime], Emulator]


class Bench(BenchBase[FbsPlc, Transport]):
    #: what a suite sees of it (hil.bench.view.suite_view)
    FACE = faces.Bench

    def __init__(self, profile: Profile, *, target: str | None = None,
                 emulator_builder: EmulatorBuilder | None = None, allow_destructive: bool = False,
                 lane: str | None = None) -> None:
        self.profile = profile
        self.lane = lane  # one lane of a run with lanes (hil.plugin.lanes): its own journal
        self.target: Target = plc_target(profile, target or None)  # at the profile's station, on every wire
        self.allow_destructive = allow_destructive or profile.safety.allow_destructive
        epoch = dt.datetime.now().replace(microsecond=0)
        if emulator_builder is None:
            emulator_builder = build_emulator
        wire_faults = None
        if profile.wire_faults and self.target.in_process:
            wire_faults = WireFaults.from_config(profile.wire_faults)  # the emulator wires' servers apply it
        self.raw: Transport = open_transport(self.target, timeout=profile.timeout, wire_faults=wire_faults,
                                             emulator_factory=lambda: emulator_builder(profile, epoch),
                                             line=profile.emulator.line)
        self.io = GuardedTransport(self.raw, profile.safety.writable, profile.safety.volatile)
        self.time: Timebase = timebase_for(self.raw.emulator, epoch, profile.time_scale)
        self.io.allow_destructive = self.allow_destructive
        # the PLC object suites hold reaches the PLC only through the guarded operations (no .inner, no _write_*)
        self.plc = FbsPlc(guarded_io(self.io), self.time, settle_scans=profile.settle_scans,
                          scan_counter=profile.scan_counter, answers_at_scan_end=profile.answers_at_scan_end)
        self.plc.configure(profile.sections)
        self.faults = Faults(self)  # bench.faults.sensor_break …; every injected fault is undone in end_test
        # Safety (issue 15): the PLC's own side effects journaled too (FUN86's defaults on an EN edge), the RTC
        # restored to its original offset from the bench's time; originals on disk before each first write.
        self.io.side_effects = self.plc.pid.side_effects
        self.io.clock = self.plc.rtc.clock()
        self.journal = self.attach_journal()
        # the fault rig's coils first (only the profile's own rigs, never the PLC itself), then the guard's recovery
        self.recovery_steps = rig_steps(rig_targets(profile), self.faults.not_the_plc)

    def plc_identity(self) -> dict[str, str] | None:
        return read_identity(self.raw)

    def wire_identity(self) -> dict[str, str] | None:
        """Unit type, OS version and memory sizes (FATEK command 53) for reports; None on a wire without it."""
        if not hasattr(self.raw, "identity"):
            return None
        ident = self.raw.identity()
        return {"unit type": f"{ident.unit_type:02X}H ({UNIT_TYPES.get(ident.unit_type, 'unknown')})",
                "os version": ident.os_text, **{f"{name} size": str(n) for name, n in ident.sizes.items()}}

    def identity(self) -> dict[str, str]:
        try:
            reason = self.raw.unreachable_reason(reg.RTC_CHIP)
            if reason:  # its first clause ("D4053 cannot be reached over …"); the suites' skips give the rest
                return {"rtc chip": f"unavailable: {reason.split(': ', 1)[0]}"}
            chip = self.plc.rtc.chip
            return {"rtc chip": f"{reg.RTC_CHIP} = {int(chip)} ({chip.name})"}
        except Exception as exc:  # noqa: BLE001 - a PLC that will not say what it is still gets tested
            return {"rtc chip": f"unavailable: {exc}"}

    # -- what suites use ----------------------------------------------------------------------------------
    def cannot_reach(self, *names: str) -> str | None:
        """Why this bench cannot read and write ``names`` (elements or ranges such as ``"R4128-R4134"``):
        unreachable over the wire, or not writable.  None when it can."""
        for name in names:
            for element in parse_range(name):
                reason = self.raw.unreachable_reason(element)
                if reason:
                    return reason
        refused = [n for n in names if not self.profile.can_write(n)]
        if refused:
            return f"{', '.join(refused)} not in the bench's [safety] writable list"
        return None

    def unreachable_reason(self, name: str) -> str | None:
        """Why this wire cannot reach ``name`` (None when it can)."""
        return self.raw.unreachable_reason(name)

    def working_elements(self, kind: str) -> list:
        """``"pid"``: the operand words of every FUN86 box that is off (:meth:`Pid.idle_operands`);
        ``"scratch"``: every word and bit of the profile's [bench] scratch ranges."""
        if kind == "pid":
            return self.plc.pid.idle_operands()
        if kind == "scratch":
            return [e for span in self.profile.scratch for e in parse_range(span)]
        return super().working_elements(kind)

    # -- per-test bookkeeping --------------------------------------------------------------------------------
    def undo_faults(self) -> None:
        self.faults.undo_all()

    def close(self) -> None:
        self.faults.close()
        self.io.close()

