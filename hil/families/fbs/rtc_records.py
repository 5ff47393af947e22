"""What the RTC's procedures return (``plc.rtc``): the flags M1952–M1955, the chip D4053, a set's outcome, a drift
measurement and a one-scan snapshot — values, below both the faces (:mod:`hil.families.fbs.faces`) and the device
layer that reads them (:mod:`hil.families.fbs.device.rtc`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from hil.families.fbs.rtc_time import RtcTime


@dataclass(frozen=True)
class RtcFlags:
    """M1952–M1955."""

    hold: bool  # M1952: read-out frozen / set trigger
    adjust_30s: bool  # M1953
    installed: bool  # M1954
    set_error: bool  # M1955: the last set was refused


@dataclass(frozen=True)
class RtcChip:
    """D4053: the chip code and its name ("none", "HT1381", "ISL1208", "S-35390A", or "unknown (n)")."""

    code: int
    name: str

    def __int__(self) -> int:
        return self.code

    @property
    def has_rate_adjust(self) -> bool:
        """Only the S-35390A takes a D4054 rate code."""
        return self.code == 3


@dataclass(frozen=True)
class SetResult:
    """The outcome of :meth:`Rtc.set`: what was sent, whether the PLC took it (M1955 = 0)."""

    sent: RtcTime
    accepted: bool
    problems: tuple[str, ...]  # the fields *we* find invalid in ``sent`` (the PLC's verdict is ``accepted``)
    #: R4128–R4134 as read with M1955, in the same frame, from a scan after the set's falling edge: what the clock
    #: shows right after the set (a suite's read-back without another round trip)
    shown: RtcTime

    @property
    def refused(self) -> bool:
        return not self.accepted

    def __bool__(self) -> bool:
        return self.accepted


@dataclass(frozen=True)
class DriftMeasurement:
    """Clock error over a measurement; positive = the PLC clock runs fast."""

    s_per_day: float
    reference_elapsed: float  # bench seconds between the first and last timed second transitions
    plc_elapsed: float  # PLC seconds between them (whole seconds)
    #: (reference t since the first transition, PLC − reference in seconds) at each timed transition
    samples: list[tuple[float, float]] = field(default_factory=list)
    resolution: float = 0.0  # s/day: worst-case error of the rate from the transitions' polling brackets

    @property
    def ppm(self) -> float:
        return self.s_per_day / 86400 * 1e6


@dataclass(frozen=True)
class RtcSnapshot:
    """R4128–R4135 and M1952–M1955 as one scan left them (:meth:`Rtc.read_all`)."""

    time: RtcTime
    hour_minute: int  # R4135
    flags: RtcFlags


__all__ = ["DriftMeasurement", "RtcChip", "RtcFlags", "RtcSnapshot", "SetResult"]
