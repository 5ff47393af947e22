"""What FUN86's procedures return (``plc.pid``): a box's alarm words decoded per point and a closed-loop trace —
values, below both the faces (:mod:`hil.families.fbs.faces`) and the device layer that reads them
(:mod:`hil.families.fbs.device.pid`)."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field

from hil.core.errors import InvalidValue
from hil.families.fbs import registers as reg
from hil.families.fbs.pid import OUTPUT_FULL, WR_NORMAL, WR_WARNING, PidInstance


@dataclass(frozen=True)
class AlarmWords:
    """WR+0 … WR+3 of one instance, decoded per point (bit b counts from Sn)."""

    instance: PidInstance
    words: tuple[int, int, int, int]
    sn: int
    alm: bool | None = None  # the box's ALM, where it was read in the same frame (:meth:`Pid.alarms`)

    def _flag(self, pair: tuple[int, int], point: int) -> bool:
        b = point - self.sn
        if not 0 <= b < reg.MAX_POINTS:
            raise InvalidValue(f"point {point} is outside this FUN86's points (Sn = {self.sn})")
        return reg.pair_bit([self.words[i] for i in pair], b)

    def normal(self, point: int) -> bool:
        return self._flag(WR_NORMAL, point)

    def warning(self, point: int) -> bool:
        return self._flag(WR_WARNING, point)

    def normal_points(self) -> list[int]:
        return [self.sn + b for b in range(reg.MAX_POINTS) if reg.pair_bit([self.words[i] for i in WR_NORMAL], b)]

    def warning_points(self) -> list[int]:
        return [self.sn + b for b in range(reg.MAX_POINTS) if reg.pair_bit([self.words[i] for i in WR_WARNING], b)]


@dataclass(frozen=True)
class Sample:
    t: float  # bench seconds since the recording started
    pv: int  # 0.1°
    sv: int  # 0.1°
    output: int  # OR, 0–16383

    @property
    def output_percent(self) -> float:
        return self.output * 100 / OUTPUT_FULL


@dataclass
class Trace:
    """A closed-loop recording of one point, plot-ready: ``columns()`` gives t, PV, SV, output lists."""

    point: int
    samples: list[Sample] = field(default_factory=list)

    def columns(self) -> dict[str, list[float]]:
        return {"t": [s.t for s in self.samples], "pv": [s.pv / 10 for s in self.samples],
                "sv": [s.sv / 10 for s in self.samples], "output": [s.output_percent for s in self.samples]}

    def to_csv(self) -> str:
        out = io.StringIO()
        writer = csv.writer(out)
        writer.writerow(["t_s", "pv", "sv", "output_percent"])
        for s in self.samples:
            writer.writerow([f"{s.t:.3f}", s.pv / 10, s.sv / 10, f"{s.output_percent:.2f}"])
        return out.getvalue()

    def settled_at(self, band: int) -> float | None:
        """The first time after which PV stayed within ±band (0.1°) of SV to the end, or None."""
        since = None
        for s in self.samples:
            if abs(s.pv - s.sv) > band:
                since = None
            elif since is None:
                since = s.t
        return since


__all__ = ["AlarmWords", "Sample", "Trace"]
