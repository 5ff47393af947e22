"""hil's public API for writing your own bench tests: the types of what the shipped fixtures give a test.

    from hil.api import Bench, Pid, Rtc

    def test_oven_heats(bench: Bench, pid: Pid) -> None: ...

Everything a test may call is declared here, typed (``py.typed``: mypy, pyright and IDEs read it) and documented;
names not exported here are internal and may change.  The Protocols are the contract: the ``bench`` fixture is a
proxy built from them (:mod:`hil.bench.view`), so a test reaches the PLC only through the guard.  Units are the
manual's: temperatures in 0.1 ° of the profile's unit, outputs 0–16383, bench seconds; each docstring names the
register or bit it reads (spec/fbs-*.md).  docs/writing-tests.md; reference: docs/api.md
(``python -m hil.api.reference``).

Fixtures (``pytest --fixtures`` lists them): ``bench`` → :class:`Bench`, ``plc`` → :class:`Plc`, ``io`` →
:class:`PlcIO`, ``rtc`` → :class:`Rtc`, ``pid`` → :class:`Pid`, ``temperature`` → :class:`Temperature`,
``faults`` → :class:`Faults`, ``measure`` → :class:`Measure`, ``report`` → :class:`Report`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

from hil.bench.faces import BenchTime, BenchView, FaultInjector
from hil.core.errors import HilError, WriteRefused
from hil.core.evidence import Expectation, StaleEvidence
from hil.core.measurement import Measurement, Outcome
from hil.families.fbs.faces import Bench, Pid, Plc, Rtc, Temperature
from hil.families.fbs.faces import FbsFaults as Faults
from hil.families.fbs.faces import FbsIO as PlcIO
from hil.families.fbs.pid import PidInstance
from hil.families.fbs.pid_records import AlarmWords, Sample, Trace
from hil.families.fbs.rtc_records import RtcChip, RtcFlags, RtcSnapshot, SetResult
from hil.families.fbs.rtc_time import RtcTime
from hil.families.fbs.temperature_records import TableView, WorkView
from hil.families.s7smart.faces import S7IO, S7Bench


class Measure(Protocol):
    """The ``measure`` fixture: ``measure("settle_time", 212.0, unit="s", low=0, high=600)`` records a measurement
    as JUnit testcase properties (``hil.measure.<name>``) and in the HTML report, and fails the test at once when
    the value is outside its limits (inclusive).  A ``@pytest.mark.measures(name, unit=…, low=…, high=…)``
    declaration states them once: the call then gives only the value (and what the declaration left out); a test
    that passes with a declared measurement still unset fails."""

    def __call__(self, name: str, value: float, *, unit: str = "", low: float | None = None,
                 high: float | None = None, note: str = "") -> Measurement:
        """Record ``value`` (``note``: what an out-of-limits value usually means, added to the failure)."""
        ...


class Report(Protocol):
    """The ``report`` fixture: data attached to this test's entry in the HTML report and its JUnit record."""

    def attach_file(self, name: str, content: str | bytes) -> object:
        """Save ``content`` beside the reports (``attachments/<test>-<name>``); the JUnit record gets
        ``hil.attachment.<name>`` with its path (None is returned when no report is being written)."""
        ...

    def attach_series(self, name: str, data: Mapping[str, Sequence[float]] | Sequence[Sequence[float]], *,
                      columns: Sequence[str] | None = None, x: str | None = None, title: str = "",
                      xlabel: str = "", ylabel: str = "", secondary: Sequence[str] = (),
                      secondary_label: str = "") -> object:
        """A plot in the HTML report: columns (``{"t": [...], "PV": [...]}``) or rows with ``columns=``; ``x``
        names the horizontal axis (default the first column); ``secondary`` columns get a right-hand axis."""
        ...


__all__ = [
    # the fixtures' types
    "Bench", "Plc", "PlcIO", "Rtc", "Pid", "Temperature", "Faults", "FaultInjector", "BenchTime", "Measure",
    "Report",
    # family-neutral and S7-200 SMART faces
    "BenchView", "S7Bench", "S7IO",
    # values the areas return
    "RtcTime", "SetResult", "RtcSnapshot", "RtcFlags", "RtcChip", "PidInstance", "AlarmWords", "Trace", "Sample",
    "TableView", "WorkView", "Measurement", "Outcome", "Expectation",
    # errors a test may expect
    "HilError", "WriteRefused", "StaleEvidence",
]
