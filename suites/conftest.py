"""Fixtures shared by the suites.  Suites reach the PLC only through the ``bench`` fixture of the hil plugin."""

from __future__ import annotations

import pytest

RTC_SET_ELEMENTS = ("R4128-R4134", "M1952")


@pytest.fixture
def rtc(bench):
    """The PLC's RTC, when this bench has one and lets the harness set it; else skip with the reason."""
    if bench.profile.rtc is not None and bench.profile.rtc.chip == 0:
        pytest.skip("the bench profile says this PLC has no RTC ([rtc] chip = 0)")
    reason = bench.cannot_reach(*RTC_SET_ELEMENTS)
    if reason:
        pytest.skip(f"cannot set the RTC on this bench: {reason}")
    return bench.plc.rtc


@pytest.fixture
def io(bench):
    """Raw element access for suites that do a procedure step by step (still guarded and journaled)."""
    return bench.plc.io


@pytest.fixture
def pid(bench):
    """plc.pid, when the bench profile describes the ladder's FUN86 boxes ([pid]); else skip with the reason."""
    if not bench.plc.pid.configured:
        pytest.skip("the bench profile has no [pid] section (where the ladder's FUN86 operands are)")
    return bench.plc.pid
