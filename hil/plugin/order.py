"""The order a session runs its tests in: tests that need a PLC straight from power-on first; and in a run with lanes
(:mod:`hil.plugin.lanes`), each lane's modules by how they use the serial line the lanes share.

On one paced line the lanes take turns by whole exchanges, the main lane first (:mod:`hil.io.shared_line`): the
others fill the line while the main lane waits for the PLC.  That works best when the main lane waits while the
others have requests to send, and sends while they wait.  A module says how it uses the line with
``pytest.mark.lane(NAME, line=…)``: ``"busy"`` — requests back to back (setting a clock field by field, a PID box's
blocks); ``"paced"`` — a burst of requests at a short cadence (a clock set every bench second): where the line is
busy it waits for it at every step, so it too should meet the main lane's waits; ``"idle"`` — few requests
between long waits for the PLC (a module's update time, the clock over minutes).  A test may say otherwise than
its module, as a marker on a test does.  The main lane runs its idle tests first and its busy ones last, every
other lane the other way round; unmarked ones go between the paced and the idle ones; within a kind the
collection's order stands."""

from __future__ import annotations

import pytest

from hil.plugin.usage import usage_error

#: ``lane(…, line=…)``'s values, in the order the main lane runs them (another lane: reversed); None: unmarked
LINE_USES: tuple[str | None, ...] = ("idle", None, "paced", "busy")


def from_power_on(item: pytest.Item) -> bool:
    """The test needs a PLC nothing in this session has touched yet (``needs("power_on_state")``)."""
    return any("power_on_state" in mark.args for mark in item.iter_markers("needs"))


def line_use(item: pytest.Item) -> str | None:
    """How ``item``'s module uses a shared line: its lane marker's ``line``, None where it says nothing."""
    mark = item.get_closest_marker("lane")
    use = mark.kwargs.get("line") if mark is not None else None
    if use not in LINE_USES:
        raise usage_error(f"{item.nodeid}: lane(…, line={use!r}) — say line=\"busy\" (requests back to back), "
                          f"\"paced\" (bursts at a short cadence) or \"idle\" (mostly waits for the PLC)")
    return use


def power_on_first(items: list[pytest.Item]) -> None:
    """A PLC straight from power-on is one nothing in this session has touched yet: those tests go first."""
    items.sort(key=lambda item: not from_power_on(item))


def by_line_use(items: list[pytest.Item], background: bool) -> None:
    """A lane's tests, power-on ones still first, then its modules by :func:`line_use`: idle first in the main lane
    (``background`` False), busy first in the others (:data:`LINE_USES`)."""
    ranks = LINE_USES[::-1] if background else LINE_USES
    items.sort(key=lambda item: (not from_power_on(item), ranks.index(line_use(item))))


__all__ = ["LINE_USES", "by_line_use", "from_power_on", "line_use", "power_on_first"]
