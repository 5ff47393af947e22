"""The PLC's real-time clock as procedures: read, set (M1952 handshake), ±30 s, D4054, drift measurement.

Everything goes through ``plc.io`` and waits through ``plc.time``, so the same code drives a bench PLC (host
time, sleeping) and the emulator (virtual time, a simulated day in milliseconds).
"""

from __future__ import annotations

import datetime as dt
import math
import random
from collections.abc import Callable
from typing import TYPE_CHECKING

from hil.bench.guard import Clock
from hil.core.errors import HilError, InvalidValue
from hil.core.timebase import nearest_whole_second, next_whole_second, wait_until
from hil.families.fbs import faces
from hil.families.fbs import registers as reg
from hil.families.fbs.address import expand
from hil.families.fbs.d4054 import code_for_rate
from hil.families.fbs.rtc_records import DriftMeasurement, RtcChip, RtcFlags, RtcSnapshot, SetResult
from hil.families.fbs.rtc_time import CENTURY_SECONDS, CHIP_NAMES, EPOCH, RtcTime

if TYPE_CHECKING:
    from hil.families.fbs.device.core import PlcCore


class RtcError(HilError):
    """The RTC procedure could not be carried out (a set that failed part-way, a clock that never ticks)."""


class RtcSetLost(RtcError):
    """The PLC reported a set as taken (M1955 = 0) but its clock does not show the time sent."""


#: R4128–R4135 then M1952–M1967 packed (bit 0 = M1952), for :meth:`Rtc.read_all`.
_SNAPSHOT_NAMES = (*reg.RTC_FIELDS, reg.RTC_HOUR_MINUTE, "W" + reg.RTC_HOLD)


#: Writes to these may set the clock (the guard journals its time first: :meth:`Rtc.clock`).
TOUCHES = expand(list(reg.RTC_FIELDS) + [reg.RTC_HOLD, reg.RTC_ADJUST_30S, reg.RTC_RATE_CODE])


class Rtc(faces.Rtc):
    """``plc.rtc``: the RTC of one FBs PLC (its contract and documentation: :class:`hil.families.fbs.faces.Rtc`)."""

    #: Bench time between polls of R4128 while a second transition is due (back to back on a real wire, where a
    #: round trip takes longer; on the emulator it is what moves virtual time on between two polls).
    poll_interval = 1 / 500

    def __init__(self, plc: PlcCore) -> None:
        self.plc = plc
        self.drift = Drift(plc, self)
        #: M1955 as last read here (None: not yet).  "An accepted set clears M1955" is the spec's [our choice]
        #: (RTC-VAL-4), so a 1 an earlier refusal left is no verdict on the next set: that one is judged by the
        #: clock read back (:meth:`_finish_set`).
        self._set_error: bool | None = None

    # -- reading --------------------------------------------------------------------------------------------
    def read(self) -> RtcTime:
        # A plain 46 read, not a 48 mixed read: the same one round trip, with 6 characters per name saved
        # (16 request bytes instead of 52 on FATEK; one FC03 either way on Modbus).
        return RtcTime.from_registers(self.plc.io.read_words(reg.RTC_SECOND, len(reg.RTC_FIELDS)))

    def read_all(self) -> RtcSnapshot:
        # One FATEK 48 frame: R4128–R4135 and WM1952 (M1952–M1967 packed in one word, 6 characters in the request
        # instead of 20 for four bit names).  Over Modbus the map coalesces it into one FC03 and one FC01.
        *fields, hour_minute, packed = self.plc.io.read_many(_SNAPSHOT_NAMES)
        flags = RtcFlags(*(bool(packed >> b & 1) for b in range(4)))
        self._set_error = flags.set_error
        return RtcSnapshot(RtcTime.from_registers(fields), hour_minute, flags)

    def read_hour_minute(self) -> int:
        return self.plc.io.read(reg.RTC_HOUR_MINUTE)

    def read_flags(self) -> RtcFlags:
        hold, adjust, installed, error = self.plc.io.read_bits(reg.RTC_HOLD, 4)
        self._set_error = bool(error)
        return RtcFlags(bool(hold), bool(adjust), bool(installed), bool(error))

    @property
    def installed(self) -> bool:
        return bool(self.plc.io.read(reg.RTC_INSTALLED))

    @property
    def chip(self) -> RtcChip:
        code = self.plc.io.read(reg.RTC_CHIP)
        return RtcChip(code, CHIP_NAMES.get(code, f"unknown ({code})"))

    def read_chip_and_rate_code(self) -> tuple[RtcChip, int]:
        """D4053 and D4054 in one register read."""
        code, rate = self.plc.io.read_words(reg.RTC_CHIP, 2)
        return RtcChip(code, CHIP_NAMES.get(code, f"unknown ({code})")), rate

    @property
    def rate_code(self) -> int:
        return self.plc.io.read(reg.RTC_RATE_CODE)

    @rate_code.setter
    def rate_code(self, code: int) -> None:
        self.plc.io.write(reg.RTC_RATE_CODE, code)

    # -- setting --------------------------------------------------------------------------------------------
    def set(self, time: dt.datetime | RtcTime, *, pulse: bool = False) -> SetResult:
        """:meth:`hil.families.fbs.faces.Rtc.set`; ``pulse``: M1952 := 0 in the very next request, as briefly as
        the wire allows (no settle between): on a port that services each request at the end of a scan the PLC
        sees the 1 for one scan only."""
        value = RtcTime.from_datetime(time) if isinstance(time, dt.datetime) else time
        # one turn on a line other lanes share: the procedure's round trips wait for it once, not each in turn
        with self.plc.io.exclusive():
            self._begin_set(value)
            return self._finish_set(value, settled=pulse)

    def clock(self) -> Clock:
        """The RTC as the bench's guard keeps it: a write to the read-out R4128–R4134, M1952/M1953 or D4054 may
        set it; before the first such write its time is journaled, and it is put back at its original offset
        from the bench's time: exactly with :meth:`sync_to` (the manual's M1952 procedure, on the original clock's
        next whole second), or at once to the nearest second with :meth:`set`."""
        def read() -> dt.datetime | None:
            try:
                return self.read().to_datetime()
            except ValueError:  # the clock holds no valid time: there is no offset to keep
                return None

        def put(when: Callable[[], dt.datetime], exact: bool) -> None:
            result = self.sync_to(when) if exact else self.set(nearest_whole_second(when()))
            if not result.accepted:
                raise HilError(f"the PLC refused the restored time {result.sent} (M1955 = 1)")
        return Clock(TOUCHES, read, put, self.plc.time, self.time_transition)

    def time_transition(self, timeout: float = 3.0) -> tuple[dt.datetime, float, float]:
        # Timed as the drift measurement times them (Drift.transition): the middle of a bracket.
        # Polls come back to back, so on a PLC that answers at the ends of its scans they would meet the scans at
        # the same phase every time, and the clock a set left on the scans' grid would be timed with the same bias
        # every time (adding up run after run): start after a random fraction of a round trip.
        # A bracket much wider than a read (a busy host, a retried request) is timed again, up to twice.
        timed: list[tuple[float, int, float]] = []
        for _ in range(3):
            started = self.plc.time.now()
            self.read()
            trip = self.plc.time.now() - started
            self.plc.time.wait(random.uniform(0, trip))
            timed.append(Drift(self.plc, self).transition(timeout))
            if timed[-1][2] <= 3 * trip:
                break
        edge, seconds, width = min(timed, key=lambda one: one[2])  # the narrowest bracket (the first of equals)
        return EPOCH + dt.timedelta(seconds=seconds), edge, width

    def sync_to_host(self) -> SetResult:
        # The registers are loaded with M1952 = 1 first and the set fires (M1952 := 0) once that second has come,
        # because the chip restarts its second at the set: this lines up its second boundaries with the host's.
        return self.sync_to(self.plc.time.calendar)

    def sync_to(self, clock: Callable[[], dt.datetime]) -> SetResult:
        """:meth:`hil.families.fbs.faces.Rtc.sync_to`, as :meth:`sync_to_host` does it.

        The bench restores a clock a test set with this: ``clock`` is then the PLC's original time carried
        forward (its original offset from the host's wall clock, whatever the host's time zone)."""
        target = next_whole_second(clock())
        value = RtcTime.from_datetime(target)
        self._begin_set(value)
        self.plc.settle_before_request()  # the 1 seen by a whole scan now, not between ``target`` and the edge
        # The chip takes the registers when the PLC services the write of M1952 := 0: taken to be half a round
        # trip after it is sent, as the transitions are timed (Drift._poll) — a read like theirs is timed for it,
        # so that where the PLC really answers within a round trip cancels between the origin and this set.
        started = self.plc.time.now()
        if not self.plc.io.read(reg.RTC_HOLD):
            raise RtcError("M1952 does not read 1 while the restored time is loaded: the set would not take")
        lead = dt.timedelta(seconds=(self.plc.time.now() - started) / 2)
        while clock() + lead > target:  # the set-up took us past it: load the next second instead
            target += dt.timedelta(seconds=1)
            value = RtcTime.from_datetime(target)
            self.plc.io.write_words(reg.RTC_SECOND, value.to_registers())  # M1952 = 1: the read-out stays frozen
        wait_until(self.plc.time, clock, target - lead)
        return self._finish_set(value, settled=True)

    def _begin_set(self, value: RtcTime) -> None:
        """M1952 := 1 and R4128–R4134 := ``value`` in one mixed write (one FATEK 49 frame; in this order)."""
        io = self.plc.io
        items = [(reg.RTC_HOLD, 1)] + list(zip(reg.RTC_FIELDS, value.to_registers()))
        io.require([name for name, _ in items], "set the RTC", RtcError)  # rather than strand M1952 at 1
        if self._set_error is None:  # (once: whether M1955 is already 1 before this harness sets anything)
            self._set_error = bool(io.read(reg.RTC_SET_ERROR))
        try:
            io.write_many(items)
        except HilError as exc:
            raise RtcError(f"setting the RTC failed part-way ({exc}); M1952 may be left at 1 with the read-out "
                           f"frozen — run `hil rtc sync <target>` once the PLC answers") from exc

    #: how far past the time sent the read-out may be right after an accepted set (the clock runs meanwhile)
    set_tolerance = 3.0

    def _finish_set(self, value: RtcTime, settled: bool = False) -> SetResult:
        """M1952 := 0 once the PLC has held the 1 across a whole scan (``settled``: it has), then M1955 and the
        read-out.

        An accepted set is read back: the PLC's read-out, copied from the chip by a scan after the set (proved by
        the scan counter where the bench declares one, by port 0's rule otherwise or where the profile says the
        port keeps it — FbsPlc.settle), must show the time sent —
        a PLC that drops the set while M1955 stays 0 raises :class:`RtcSetLost`.  Where M1955 was already 1 (an
        earlier refusal) and still is, that read-back is the verdict on a valid time: whether an accepted set clears
        M1955 is the spec's [our choice] (RTC-VAL-4), so the 1 may be the earlier refusal's."""
        if not settled:
            self.plc.settle_before_request()  # the 1 seen by a whole scan before the falling edge
        started = self.plc.time.now()
        self.plc.io.write(reg.RTC_HOLD, 0)
        # the read of M1955 ends a scan too (with a scan counter, read in the same frame as the counter)
        refused, *fields = self.plc.read_settled([reg.RTC_SET_ERROR, *reg.RTC_FIELDS])
        shown = RtcTime.from_registers(fields)
        # modulo the chip's century: a set of 2099-12-31 23:59:59 may read back as 2000-01-01, one second on
        ahead = ((shown.to_datetime() - value.to_datetime()).total_seconds() % CENTURY_SECONDS
                 if shown.is_valid and value.is_valid else None)
        slack = self.set_tolerance + (self.plc.time.now() - started)
        shows_sent = ahead is not None and 0 <= ahead <= slack
        earlier, self._set_error = self._set_error, bool(refused)
        result = SetResult(value, not refused or bool(earlier and shows_sent), tuple(value.validate()), shown)
        if result.accepted and value.is_valid:
            if not shows_sent:
                raise RtcSetLost(f"the PLC took the set (M1955 = 0) but its clock shows {shown} after it, not "
                                 f"{value} (sent): the set was lost (M1952 edge not seen by a scan?)")
            weekday = _weekday_after(value, shown)
            if weekday is not None and shown.weekday != weekday:
                raise RtcSetLost(f"the PLC took the set (M1955 = 0) but its clock shows weekday {shown.weekday} "
                                 f"({shown}) after it, not {weekday}: the weekday sent ({value.weekday}) was lost")
        return result

    def adjust_30s(self) -> None:
        """:meth:`hil.families.fbs.faces.Rtc.adjust_30s`: M1953 0 → 1 (rising edge), settle, back to 0.

        The PLC must see a 0 before the 1.  A settled read of M1953 that shows 0 proves it: the read is from a frame
        a whole scan after every earlier request (the scan counter in the same frame, where the bench declares one;
        port 0's rule otherwise), so that scan ran with the 0 read, whoever wrote it last, and the 1 lands at the
        frame's scan end at the earliest.  Only a 1 read costs a write of 0 and a whole scan holding it."""
        io = self.plc.io
        with io.exclusive():  # (one turn on a shared line, as a set)
            if self.plc.read_settled([reg.RTC_ADJUST_30S])[0]:
                io.write(reg.RTC_ADJUST_30S, 0)
                self.plc.settle_before_request()  # the 0 held across a whole scan (proved with a scan counter)
            io.write(reg.RTC_ADJUST_30S, 1)
            self.plc.settle_before_request()  # the write of 0 below is serviced a scan later at the earliest
            io.write(reg.RTC_ADJUST_30S, 0)
            self.plc.settle_before_request()  # the 0 seen before anyone looks at the effect or fires again


class Drift:
    """``plc.rtc.drift``: measure the clock's rate error against the bench's reference time, and correct it."""

    def __init__(self, plc: PlcCore, rtc: Rtc) -> None:
        self.plc = plc
        self.rtc = rtc
        self._edge: float | None = None  # reference time of the last timed second transition

    def measure(self, duration: float, *, transitions: int = 3, checkpoints: int = 8,
                timeout: float = 3.0) -> DriftMeasurement:
        """Clock error in s/day over about ``duration`` bench seconds.

        The RTC shows whole seconds, so we time its second *transitions*: R4128 is polled every
        ``Rtc.poll_interval`` and each transition is placed midway between the last poll that showed the old
        second and the first that showed the new one.  ``transitions`` consecutive ones are timed at the start
        and again at the end, and the rate is the least-squares slope of (PLC − reference) over all of them, so
        polling jitter averages out.  One more transition is timed at each of ``checkpoints`` evenly spaced
        moments in between, so the samples show the error growing over time (the report plots them) and a clock
        whose rate changes mid-measurement shows as a bend.  Leave D4054 as it is: this measures the clock as it
        runs now.
        """
        if transitions < 1:
            raise InvalidValue(f"transitions must be at least 1, not {transitions}")
        self._edge = None  # a new measurement learns the phase afresh (the clock may have been set since)
        if duration < transitions + 2:
            raise InvalidValue(f"a drift measurement needs more than {transitions + 2} s, not {duration} s")
        return _fit(self._timed_transitions(duration, transitions, checkpoints, timeout))

    def _timed_transitions(self, duration: float, transitions: int, checkpoints: int,
                           timeout: float) -> list[tuple[float, int, float]]:
        """``transitions`` second transitions timed at the start and at the end of ``duration`` bench seconds, and
        one at each of ``checkpoints`` evenly spaced moments between (as :meth:`transition` times them)."""
        # Stagger the start of each timing by a fraction of the poll interval so that the polls fall at different
        # phases of the chip's second (on the emulator they would otherwise land identically every time).
        step = self.rtc.poll_interval / transitions
        first = [self.transition(timeout, i * step) for i in range(transitions)]
        # Scheduled on the bench clock from the first transition, so the measurement spans the duration asked
        # (to the PLC's whole second): each timing starts half a second before the second it is to catch, and the
        # last group ends at first + duration.  A short measurement has room for fewer checkpoints (none at 10 s).
        clock, t0 = self.plc.time, first[0][0]
        last_start = t0 + duration - (transitions - 1) - 0.5
        middle: list[tuple[float, int, float]] = []
        for k in range(1, checkpoints + 1):
            at = t0 + k * duration / (checkpoints + 1) - 0.5
            if at <= clock.now() or at + 1.5 > last_start:
                continue
            clock.wait(at - clock.now())
            middle.append(self.transition(timeout))
        if last_start > clock.now():
            clock.wait(last_start - clock.now())
        last = [self.transition(timeout, i * step) for i in range(transitions)]
        return first + middle + last

    def measure_until(self, resolution: float, max_duration: float, *, transitions: int = 3,
                      checkpoints: int = 8, timeout: float = 3.0) -> DriftMeasurement:
        """A drift measurement long enough for its resolution to come out below ``resolution`` s/day, if the
        bench allows that within ``max_duration`` bench seconds (else the longest allowed: the caller sees the
        resolution it got and must not decide on it).

        One second transition is timed first to learn how wide this bench's brackets are (polling interval plus
        a round trip); the duration is chosen for half the resolution asked, as brackets vary.  Brackets can vary
        more than that (a PLC whose scans differ in length, a busy wire): a measurement that comes out too coarse
        is taken once more, as much longer as its resolution says (resolution falls as 1/duration), within
        ``max_duration``."""
        _, _, width = self.transition(timeout)
        needed = 2 * max(width, self.rtc.poll_interval) * 86400 / resolution
        duration = min(max_duration, max(needed, transitions + 3.0))
        result = self.measure(duration, transitions=transitions, checkpoints=checkpoints, timeout=timeout)
        if result.resolution < resolution or duration >= max_duration:
            return result
        longer = min(max_duration, duration * 1.5 * result.resolution / resolution)
        return self.measure(longer, transitions=transitions, checkpoints=checkpoints, timeout=timeout)

    def compensate(self, rate: float) -> int:
        """Write the manual's D4054 code for a clock error of ``rate`` s/day and return it.

        ``rate`` is the error measured with no correction in force (D4054 = 0): the code replaces, it does not
        add to, whatever D4054 held.
        """
        code = code_for_rate(rate)
        self.rtc.rate_code = code
        return code

    # -- timing one second transition -------------------------------------------------------------------------
    #: bench seconds before an expected transition that polling starts, plus this fraction of the time since the
    #: last timed one (the PLC's second may differ from the bench's by a crystal error and D4054's ±192 ppm)
    lead = 0.05
    lead_per_second = 5e-4

    def transition(self, timeout: float, phase: float = 0.0) -> tuple[float, int, float]:
        """The next second transition: (reference time, PLC seconds since 2000 just after it, bracket width).

        The reference time is the middle of the bracket between the last poll that showed the old second and
        the first that showed the new one, each poll placed at the middle of its round trip (where the PLC
        answered it, as far as one can tell from here — the guard's exact clock restore takes the moment of a set
        the same way, so that where a PLC really answers within a round trip cancels between the two).
        Once one transition is timed the next is expected a whole number of seconds later: the wait until just
        before it is one sleep, and the polls around it come back to back, so a bracket is about one round trip
        (not a polling interval) and few requests are spent per second.
        """
        clock = self.plc.time
        if phase > 0:
            clock.wait(phase)
        old, before = self._poll()
        deadline = before + timeout
        if self._edge is not None:
            since = before - self._edge
            lead = self.lead + self.lead_per_second * since
            upcoming = self._edge + math.ceil(since + lead)  # the first expected transition not yet too close
            if upcoming - lead > before:
                clock.wait(upcoming - lead - before)
                # a transition earlier than expected is simply not this one: time the next
                old, before = self._poll()
                deadline = before + timeout
        while True:
            clock.wait(self.rtc.poll_interval)
            current, after = self._poll()
            if current.second != old.second:
                self._edge = (before + after) / 2
                return self._edge, _seconds(current), after - before
            if after > deadline:
                raise RtcError(f"R4128 stayed at {old.second} for {after - before:.2f} s of bench time: the RTC "
                               f"is not running (chip missing, M1952 left at 1?)")
            before = after

    def _poll(self) -> tuple[RtcTime, float]:
        """R4128–R4134 and the reference time at the middle of the read's round trip."""
        started = self.plc.time.now()
        shown = self.rtc.read()
        return shown, (started + self.plc.time.now()) / 2


def _fit(timed: list[tuple[float, int, float]]) -> DriftMeasurement:
    """The clock's rate error from its timed transitions (bench time, PLC seconds, bracket width): the
    least-squares slope of (PLC − reference) over them, so polling jitter averages out, with its worst-case error."""
    t0, s0, _ = timed[0]
    samples = []
    for t, s, _ in timed:
        shown = (s - s0) % CENTURY_SECONDS  # the chip's year may wrap 2099 → 2000 mid-measurement
        samples.append((t - t0, shown - (t - t0)))
    xs = [x for x, _ in samples]
    ys = [y for _, y in samples]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    slope = sum((x - mx) * (y - my) for x, y in samples) / sxx
    reference_elapsed = xs[-1]
    plc_elapsed = reference_elapsed + ys[-1]
    # Each transition is known to ± half its bracket, so the least-squares slope is off by at most
    # Σ |x − x̄| · width / 2 / Σ (x − x̄)²: a hard bound, in which one wide bracket (a slow round trip on a busy
    # host) weighs only as much as its sample does, not as the whole measurement's worst case.
    widths = [width for _, _, width in timed]
    bound = sum(abs(x - mx) * w / 2 for x, w in zip(xs, widths)) / sxx
    return DriftMeasurement(slope * 86400, reference_elapsed, plc_elapsed, samples, resolution=bound * 86400)


def _weekday_after(sent: RtcTime, shown: RtcTime) -> int | None:
    """The weekday R4134 must show at ``shown`` after a set of ``sent``: the one sent, advanced by one for each day
    the clock has run into since.  None when ``sent`` carried a weekday its date does not have: the manual does not say
    whether the PLC keeps such a weekday or derives it from the date, so nothing is expected of it (nor across the
    2099 → 2000 wrap, where the two differ)."""
    if sent.weekday != sent.with_weekday_from_date().weekday:
        return None
    days = (shown.to_datetime().date() - sent.to_datetime().date()).days
    if days < 0:  # run across the wrap 2099 → 2000: the weekday there is the spec's [our choice] (RTC-RUN-3),
        return None  # which the suites check, not every set
    return (sent.weekday + days) % 7


def _seconds(t: RtcTime) -> int:
    if not t.is_valid:
        raise RtcError(f"the PLC shows an invalid time {t} ({', '.join(t.validate())}) while measuring drift")
    return int((t.to_datetime() - EPOCH).total_seconds())


__all__ = ["Drift", "DriftMeasurement", "Rtc", "RtcChip", "RtcError", "RtcFlags", "RtcSetLost", "RtcSnapshot",
           "SetResult"]
