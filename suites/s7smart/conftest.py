"""Fixtures of the S7-200 SMART suites.  Every module here is marked ``family("s7-200smart")``: on an FBs bench
the plugin skips it (and the FBs suites on an S7 bench), with the reason."""

from __future__ import annotations

import pytest


@pytest.fixture
def clock(bench):
    """The clock test program's procedures (``set``, ``set_int``, ``read``), when the bench has one."""
    rtc = bench.plc.rtc
    if rtc is None:
        pytest.skip("the bench profile has no [s7rtc] section: no clock test program on this PLC")
    lay = rtc.layout
    reason = bench.cannot_reach(str(lay.set_trigger), str(lay.read_trigger), f"VB{lay.set_buffer.byte}-"
                                f"VB{lay.set_buffer.byte + 7}")
    if reason:
        pytest.skip(f"cannot set the clock on this bench: {reason}")
    yield rtc
    rtc.release()  # never leave a trigger held for the next test

