"""A bench: the profile made live — the PLC behind its guard, the bench's time, and the per-test restore.

The pytest plugin builds one Bench per session; suites see it as the ``bench`` fixture.
"""

from __future__ import annotations

import datetime as dt
import time as _time
from typing import Callable

from hil.families.fbs.address import parse_range
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs import registers as reg
from hil.bench.base import BenchBase
from hil.bench.profile import Profile
from hil.core.timebase import Timebase, timebase_for
from hil.families.fbs.transport.base import Transport
from hil.families.fbs.transport.factory import open_transport
from hil.families.fbs.transport.guard import GuardedTransport, expand
from hil.io.url import Target, parse_target

EmulatorBuilder = Callable[[Profile, dt.datetime], Emulator]

# Writes to these mean the RTC may be left off host time: sync it after the test.
_RTC_TOUCHES = expand(list(reg.RTC_FIELDS) + [reg.RTC_HOLD, reg.RTC_ADJUST_30S, reg.RTC_RATE_CODE])


class Bench(BenchBase):
    def __init__(self, profile: Profile, *, target: str | None = None,
                 emulator_builder: EmulatorBuilder | None = None, allow_destructive: bool = False) -> None:
        self.profile = profile
        self.target: Target = parse_target(target or profile.target)
        self.allow_destructive = allow_destructive or profile.safety.allow_destructive
        epoch = dt.datetime.now().replace(microsecond=0)
        if emulator_builder is None:
            from hil.families.fbs.sim.build import build_emulator
            emulator_builder = build_emulator
        wire_faults = None
        if profile.wire_faults and self.target.in_process:
            from hil.sim.wire_faults import WireFaults
            wire_faults = WireFaults.from_config(profile.wire_faults)  # the emulator wires' servers apply it
        self.raw: Transport = open_transport(self.target, timeout=profile.timeout, wire_faults=wire_faults,
                                             emulator_factory=lambda: emulator_builder(profile, epoch))
        self.io = GuardedTransport(self.raw, profile.safety.writable, profile.safety.volatile)
        self.time: Timebase = timebase_for(self.raw.emulator, epoch, profile.time_scale)
        self.io.allow_destructive = self.allow_destructive
        from hil.families.fbs.transport.guarded_io import guarded_io
        # the PLC object suites hold reaches the PLC only through the guarded operations (no .inner, no _write_*)
        self.plc = FbsPlc(guarded_io(self.io), self.time, settle_scans=profile.settle_scans,
                          scan_counter=profile.scan_counter)
        if "temperature" in profile.sections:
            self.plc.temperature.config = profile.sections["temperature"]
        if "pid" in profile.sections:
            self.plc.pid.config = profile.sections["pid"]
        from hil.families.fbs.faults import Faults
        self.faults = Faults(self)  # bench.faults.sensor_break …; every injected fault is undone in end_test
        # Safety (issue 15): originals on disk before each first write, the PLC's own side effects journaled too,
        # the clock restored to its original offset from the host's wall clock.
        self.journal = None
        if not self.target.in_process:
            from hil.core.lock import lock_key
            from hil.core.journal import Journal
            self.journal = Journal(lock_key(str(self.target)))
            self.io.durable = self.journal
        self.io.side_effects = self.plc.pid.side_effects
        self.io.before_write = self._before_write
        #: (PLC time, reference) before the session's first write that touched the clock; kept (and journaled)
        #: until the session's end puts the clock back exactly, so that per-test restores never compound
        self.clock_origin: tuple[dt.datetime, float] | None = None
        #: the clock differs from its original offset: a test set it and it is not put back yet
        self.clock_changed = False

    def recover(self):  # noqa: ANN201 - hil.families.fbs.recovery.Recovery, or None for an in-process emulator
        """Replay what a dead run left in this bench's journal (before anything else; see hil.families.fbs.recovery)."""
        if self.journal is None:
            return None
        from hil.families.fbs.recovery import recover
        return recover(self.journal, self.raw, self.time)

    # -- the clock, journaled as an offset ---------------------------------------------------------------------
    def _reference(self) -> float:
        """The bench's reference time in PLC seconds: virtual time on the in-process emulator, else the host's
        wall clock (UTC seconds, whatever TZ says) times the profile's time scale."""
        return self.time.now() if self.time.virtual else _time.time() * self.profile.time_scale

    def _before_write(self, base: list) -> None:
        if not _RTC_TOUCHES.intersection(base):
            return
        self.clock_changed = True
        if self.clock_origin is not None:
            return
        from hil.families.fbs.rtc_time import RtcTime
        try:
            plc_time = RtcTime.from_registers(self.raw.read_words(reg.RTC_SECOND, len(reg.RTC_FIELDS))).to_datetime()
        except ValueError:  # the clock held no valid time: there is no offset to keep; sync to host time then
            return
        self.clock_origin = (plc_time, self._reference())
        if self.journal is not None:
            self.journal.set_clock(plc_time, _time.time(), self.profile.time_scale)

    def _original_clock(self) -> dt.datetime:
        plc_time, ref = self.clock_origin  # type: ignore[misc]
        return plc_time + dt.timedelta(seconds=self._reference() - ref)

    def restore_clock(self, exact: bool = True) -> None:
        """Put the clock back at its original offset (or on host time when it held no valid time).

        ``exact`` waits for the original clock's next whole second before the set fires, because the chip
        restarts its second at a set (up to a second of bench time); between two tests the set fires at once,
        with the original time rounded to the nearest second (within ±0.5 s), and the session's end, or the
        next run's recovery if this one dies, makes it exact — both from the session's first origin, so the
        per-test errors never add up."""
        from hil.core.errors import RestoreError
        clock = self._original_clock if self.clock_origin is not None else self.time.calendar
        if exact:
            result = self.plc.rtc.sync_to(clock)
        else:
            result = self.plc.rtc.set(clock() + dt.timedelta(microseconds=500_000))
        if not result.accepted:
            raise RestoreError([("RTC", 0, f"the PLC refused the restored time {result.sent} (M1955 = 1)")])
        self.clock_changed = False

    def finish(self) -> None:
        """The session ends: the clock back at its original offset exactly, and its journal entry cleared."""
        if self.clock_origin is None and not self.clock_changed:
            return
        try:
            self.restore_clock(exact=True)
            self.clock_origin = None
            if self.journal is not None:
                self.journal.drop_clock()
        finally:
            self.io.restore()  # the set's own writes (M1952, R4128–R4134), journaled like a test's
            self.io.start_journal()

    def identity(self) -> dict[str, str]:
        try:
            reason = self.raw.unreachable_reason(reg.RTC_CHIP)
            if reason:
                return {"rtc chip": f"unavailable: {reason}"}
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

    # -- per-test bookkeeping --------------------------------------------------------------------------------
    def begin_test(self, test_id: str = "") -> None:
        """A test starts: first retry any restore that failed before (a RestoreError here means the PLC is
        still not as it was found), then start its journal."""
        if self.journal is not None:
            self.journal.test = test_id
        if self.clock_changed:
            self.restore_clock(exact=False)
        if self.io.unrestored:
            self.io.restore()
        self.io.start_journal()

    def end_test(self) -> None:
        """Put the PLC back as it was found: injected faults, journaled values, then the RTC if a test touched it.

        Idempotent: a second call finds nothing left to undo."""
        try:
            try:
                self.faults.undo_all()  # first: a plc-bit injector's own writes are then restored and verified
            finally:
                # The sync comes before the one restore: its writes (M1952) join the same journal, so one
                # write-back and one read-back verify the test's and the sync's writes together (6 round trips
                # on FATEK, not 9 with a restore on each side of the sync).
                try:
                    if self.clock_changed:
                        self.restore_clock(exact=False)
                finally:
                    self.io.restore()
        finally:
            self.io.start_journal()

    def reopen(self) -> None:
        """Reconnect the wire after a failure (an emulator's server keeps running; only the client reconnects)."""
        self.raw.reopen()

    def alive(self) -> str | None:
        """None when the PLC answers (reconnecting once if needed), else why not."""
        try:
            self.io.status()
            return None
        except Exception as first:  # noqa: BLE001 - any failure here means "not answering"
            try:
                self.raw.reopen()
                self.io.status()
                return None
            except Exception as exc:  # noqa: BLE001
                return f"{first}; reconnecting: {exc}"

    def close(self) -> None:
        self.faults.close()
        self.io.close()

