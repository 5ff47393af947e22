"""What the FBs family adds to reports (:mod:`hil.core.registry`): its suites' areas, and the plots its suites
attach — a clock's drift and a PID loop's trace (``report.attach_drift(…)``, ``report.attach_pid(…)``)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from hil.core.registry import REPORT_AREAS, REPORT_PLOTS

for _key, _area in (("test_rtc_drift", "drift"), ("drift", "drift"), ("test_rtc", "RTC"),
                    ("test_temperature", "temperature"), ("test_pid", "PID")):
    REPORT_AREAS.register(_key, _area)


def attach_drift(report: Any, measurement: Any, name: str = "drift", title: str = "") -> Any:
    """A :class:`~hil.families.fbs.device.rtc.DriftMeasurement`'s samples: PLC − reference (s) over reference
    time (h)."""
    rows = [(t / 3600.0, d) for t, d in measurement.samples]
    return report.attach_series(name, rows, columns=("reference time", "PLC − reference"),
                                title=title or f"clock drift {measurement.s_per_day:+.3f} s/day",
                                xlabel="reference time (h)", ylabel="PLC − reference (s)")


def attach_pid(report: Any, trace: Sequence[Sequence[float]], name: str = "pid", title: str = "PID closed loop",
               unit: str = "", output_unit: str = "") -> Any:
    """A closed-loop trace of ``(t, PV, SV, output)`` rows; the output is drawn on its own axis."""
    return report.attach_series(name, trace, columns=("t", "PV", "SV", "output"), title=title,
                                xlabel="time (s)", ylabel=f"PV, SV{f' ({unit})' if unit else ''}",
                                secondary=("output",),
                                secondary_label=f"output{f' ({output_unit})' if output_unit else ''}")


REPORT_PLOTS.register("drift", attach_drift)
REPORT_PLOTS.register("pid", attach_pid)
