"""The FBs family's pytest fixtures, shipped with the plugin (entry point ``hil-fbs`` in the ``pytest11`` group):
any test directory gets them, and the bundled suites use the same ones.  ``pytest --fixtures`` lists them."""

from __future__ import annotations

from typing import TYPE_CHECKING

import pytest

from hil.families.fbs import registers as reg

if TYPE_CHECKING:
    from hil.families.fbs.faces import Bench, Pid, Rtc, Temperature

#: the work block's execution code while the modules measure (spec/fbs-temperature.md, TW+0 high byte)
MEASURING = 0x56
#: what setting the clock writes (the manual's M1952 procedure): a bench that cannot write them cannot set it
RTC_SET_ELEMENTS = (f"{reg.RTC_FIELDS[0]}-{reg.RTC_FIELDS[-1]}", reg.RTC_HOLD)


@pytest.fixture
def rtc(bench: Bench) -> Rtc:
    """The PLC's real-time clock (``hil.api.Rtc``): ``rtc.read().to_datetime()``, ``rtc.set(datetime)``,
    ``rtc.read_hour_minute()`` (R4135) … — compare it with ``bench.time.calendar()``, the bench's time (virtual on
    the in-process emulator), never with ``datetime.now()``.  The clock is put back at its original offset after
    the test (after the module's last, where the module declares ``pytest.mark.working_state("clock")``).  Skips
    with the reason when the profile says there is no RTC (``[rtc] chip = 0``) or the bench cannot write
    R4128–R4134 and M1952."""
    rtc_section = bench.profile.rtc
    if rtc_section is not None and rtc_section.chip == 0:
        pytest.skip("the bench profile says this PLC has no RTC ([rtc] chip = 0)")
    reason = bench.cannot_reach(*RTC_SET_ELEMENTS)
    if reason:
        pytest.skip(f"cannot set the RTC on this bench: {reason}")
    return bench.plc.rtc


@pytest.fixture
def pid(bench: Bench) -> Pid:
    """The ladder's FUN86 boxes (``hil.api.Pid``) the profile's ``[[pid.instances]]`` describe:
    ``pid.instance("oven")``, ``pid.enable(box)``, ``pid.set_set_point(point, tenths)``, ``pid.alarm_words(box)``,
    ``pid.record(point, seconds)`` …  EN's rising edge loads FUN86's default gains: set your own after enabling.
    Skips with the reason when the profile has no ``[pid]``."""
    if not bench.plc.pid.configured:
        pytest.skip("the bench profile has no [pid] section (where the ladder's FUN86 operands are)")
    return bench.plc.pid


@pytest.fixture
def temperature(bench: Bench) -> Temperature:
    """The temperature modules (``hil.api.Temperature``) where the profile's ``[temperature]`` says the ladder keeps
    their table, readings and work block: ``temperature.reading(point)`` (0.1 °), ``wait_for_update()``,
    ``wait_until(event)``.  A point reads 0 until the modules have measured it once: when they are not measuring
    yet (execution code ≠ 56H, just powered on) the fixture waits for one update first.  Skips with the reason when
    the profile has no ``[temperature]``."""
    temperature = bench.plc.temperature
    if not temperature.configured:
        pytest.skip("the bench profile has no [temperature] section (where the ladder keeps the table)")
    if temperature.read_work().execution_code != MEASURING:
        temperature.wait_for_update()
    return temperature
