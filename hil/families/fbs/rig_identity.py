"""Whether a fault rig is a separate device and not the PLC under test: one decision, for injection and recovery.

A Modbus fault rig is switched by coil number; pointed at the PLC's own Modbus port, "coil 0" is the PLC's Y0.  So
before a rig coil is switched — by a test's injector (:class:`hil.families.fbs.faults.Faults`) or by the recovery of
a dead run's coils (:mod:`hil.families.fbs.recovery`, on every path: a run, ``hil restore``, ``hil rtc sync``) —
the rig must be *proven* another device.  What cannot be decided is refused, never assumed.

The proof reads the PLC's RTC read-out R4128–R4134 where the FBs Modbus map serves it (holding 4128…) on the rig:

* an answer of Modbus exception 01 (no holding registers) or 02 (none there) — what a relay module answers, and
  what an FBs's own Modbus port never does (it serves R4128… there) — proves a separate device;
* values that the PLC's running clock, read over the bench's wire just before and just after, does not hold
  prove one too; the same values prove the rig *is* the PLC;
* anything else — no answer, another exception, a PLC clock that reads 0 or cannot be read, a clock that moved
  while the rig was read (three tries) — decides nothing, and is refused.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from hil.core.errors import HilError, PlcErrorReply
from hil.core.lock import lock_key
from hil.families.fbs.protocol.modbus_map import to_modbus
from hil.families.fbs.registers import RTC_SECOND as RTC_FIRST
from hil.families.fbs.rig import RigLink, rig_wire
from hil.io.url import parse_target

RTC_WORDS = 7  # R4128–R4134: second, minute, hour, day, month, year, weekday
#: Modbus exceptions that say a device has no FBs memory: 01 illegal function, 02 illegal data address
NO_FBS_MEMORY = frozenset({"1", "2"})
WAIT = 2.0  # seconds the rig has to answer, at most (the profile's timeout when shorter)
TRIES = 3  # comparisons tried when the PLC's clock moves on while the rig is read
ADVICE = "[faults.*] target must name the relay module (powered, at its own address), never the PLC"

Words = list[int]


def rig_refusal(rig: str, plc: str | None, transport: Any, timeout: float) -> str | None:
    """Why the fault rig at URL ``rig`` may not be switched: it is the PLC under test (endpoint ``plc``, reached over
    ``transport``, whose requests wait ``timeout`` seconds), or whether it is cannot be told.  None only once it is
    proven a separate device."""
    if plc is not None and lock_key(rig) == lock_key(plc):
        return f"{rig} is the PLC under test ({plc}); {ADVICE}"
    try:
        link = RigLink(rig_wire(parse_target(rig), min(WAIT, timeout), retries=0))
    except HilError as exc:
        return _undecided(rig, f"it could not be reached ({exc})")
    try:
        return _compare(rig, plc, transport, lambda: link.read_registers(to_modbus(RTC_FIRST).pdu, RTC_WORDS))
    finally:
        link.close()


def _compare(rig: str, plc: str | None, transport: Any, read_rig: Callable[[], Words]) -> str | None:
    """The RTC read-out on the rig against the PLC's, read before and after it (see the module's docstring)."""
    for _ in range(TRIES):
        before = _plc_clock(transport)
        try:
            there = read_rig()
        except PlcErrorReply as exc:
            if exc.code in NO_FBS_MEMORY:  # no FBs memory there: a relay module, not an FBs's Modbus port
                return None
            return _undecided(rig, f"it answered a read of {RTC_FIRST}… with {exc}")
        except HilError as exc:
            return _undecided(rig, f"it did not answer a read of {RTC_FIRST}… ({exc})")
        after = _plc_clock(transport)
        for clock in (before, after):
            if isinstance(clock, str):
                return _undecided(rig, f"it serves registers at {RTC_FIRST}… and {clock}")
        if not any(before) or not any(after):
            return _undecided(rig, f"it serves registers at {RTC_FIRST}… and the PLC's clock reads 0 (a running "
                                   f"clock would tell them apart)")
        if there in (before, after):
            return (f"{rig} serves the PLC's own memory (its RTC read-out {RTC_FIRST}… reads there as over "
                    f"{plc or 'the bench wire'}): it is the PLC's own Modbus port; {ADVICE}")
        if before == after:  # the clock stood still while the rig was read: the rig holds what it never held
            return None
    return _undecided(rig, f"the PLC's clock moved on while the rig's {RTC_FIRST}… was read, {TRIES} times over")


def _plc_clock(transport: Any) -> Words | str:
    """The PLC's RTC read-out over the bench's wire, or why it cannot be read."""
    reason = transport.unreachable_reason(RTC_FIRST)
    if reason:
        return f"the PLC's clock cannot be read over the bench's wire ({reason})"
    try:
        return list(transport.read_words(RTC_FIRST, RTC_WORDS))
    except HilError as exc:
        return f"reading the PLC's clock failed ({exc})"


def _undecided(rig: str, why: str) -> str:
    return f"{rig} cannot be told apart from the PLC under test: {why}; {ADVICE}"


__all__ = ["rig_refusal"]
