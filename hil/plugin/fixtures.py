"""Fixtures every bench has, whatever its family (the family's own — ``rtc``, ``pid``, ``temperature`` for an FBs —
come with the family: :mod:`hil.families.fbs.fixtures`).  ``pytest --fixtures`` lists them with these docstrings.

PYTEST_DONT_REWRITE (no asserts here: see ``pytest_plugins`` in :mod:`hil.plugin.pytest_plugin`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from hil.bench.faces import BenchView, Faults, PlcIO


@pytest.fixture
def plc(bench: BenchView) -> Any:
    """The PLC under test (``bench.plc``; ``hil.api.Plc`` on an FBs bench): its guarded ``io`` and its areas."""
    return bench.plc


@pytest.fixture
def io(bench: BenchView) -> PlcIO:
    """The PLC's elements (``bench.plc.io``; ``hil.api.PlcIO`` on an FBs bench), for a procedure done step by step:
    ``io.read("R100")``, ``io.read_words("R4128", 8)``, ``io.write("M1000", 1)``.  Every write goes through the
    guard: refused before a byte is sent unless the profile's ``[safety] writable`` lists it, journaled, and put
    back (then read back) when the test ends, pass or fail."""
    io: PlcIO = bench.plc.io
    return io


@pytest.fixture
def faults(bench: BenchView) -> Faults:
    """The bench's fault injectors by the names of the profile's ``[faults.<name>]`` (``faults.get("heater_open")``,
    ``faults.unavailable(name)`` for a skip's reason).  Every fault injected is repaired when the test ends.
    Skips when the bench has none."""
    found: Faults | None = getattr(bench, "faults", None)
    if found is None:
        pytest.skip(f"bench {bench.name!r} has no fault injectors")
    return found
