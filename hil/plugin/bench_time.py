"""Timeouts that fit the bench: a bench test's pytest timeout is the bench time it plans plus a margin.

A suite test states the bench seconds it plans (its waits, drift durations, R4007 …) with
``@pytest.mark.bench_time(seconds_or_callable, reason=…)``; a callable gets the bench profile (e.g. the drift test's
``[rtc] drift_max_hours``).  On a PLC on a wire those seconds pass at the profile's ``time_scale``; on the
in-process emulator they are virtual and cost next to nothing.  The timeout is that wall time plus
:data:`MARGIN`; the pyproject default (60 s) is left for the harness's own tests.
"""

from __future__ import annotations

from typing import Any

import pytest

#: wall seconds on top of the planned bench time (connecting, settling, restoring, a slow shared host)
MARGIN = 60.0
#: bench seconds a suite test that states nothing may take (a few manual worst cases of polling)
DEFAULT_PLANNED = 60.0

MARKER = ("bench_time(seconds | callable(profile) -> seconds, reason=…): the bench seconds the test plans (waits, "
          "measurement durations); its timeout is that wall time at the profile's time_scale plus a margin")


def planned_seconds(item: pytest.Item, profile: Any) -> float:
    marker = item.get_closest_marker("bench_time")
    if marker is None or not marker.args:
        return DEFAULT_PLANNED
    planned = marker.args[0]
    return float(planned(profile) if callable(planned) else planned)


def bench_timeout(item: pytest.Item, profile: Any, in_process: bool) -> float:
    """The wall seconds ``item`` may take on this bench."""
    wall = 0.0 if in_process else planned_seconds(item, profile) / profile.time_scale
    return round(wall + MARGIN, 1)


def apply(items: list[pytest.Item], profile: Any, in_process: bool) -> None:
    """Give every bench test without an explicit ``timeout`` marker its bench timeout."""
    for item in items:
        if "bench" not in getattr(item, "fixturenames", ()) or item.get_closest_marker("timeout") is not None:
            continue
        item.add_marker(pytest.mark.timeout(bench_timeout(item, profile, in_process)))
