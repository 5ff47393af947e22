"""Recovery first, the FBs side: a fault rig's coils, and recovery over a command's direct transport.

The rules — replay a dead run's journal before anything else, only as far as it can be proven, verify it, say so —
are the guard's (:meth:`hil.bench.guard.Guard.recover`, :mod:`hil.bench.replay`).  This module adds what only an
FBs bench has: the Modbus fault rig, whose coils are put back (and read back) first — only on a rig the profile
names and proven not to be the PLC itself, only the coils the profile lets its injectors switch, and only while a
coil still holds what the run switched it to — and
:func:`recover` for the CLI's writing commands (``hil rtc set``, ``hil drift measure --apply``), which hold a direct
transport rather than a bench.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from hil.bench.guard import Recovery, RecoveryStep
from hil.bench.replay import age_problem
from hil.core.errors import HilError
from hil.core.journal import COILS, Journal
from hil.core.lock import lock_key
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.injectors.modbus_coil import ModbusCoilSensorBreak
from hil.families.fbs.rig import GuardedRig, RigLink, rig_wire
from hil.families.fbs.rig_identity import rig_refusal
from hil.families.fbs.transport.guard import GuardedTransport
from hil.io.url import parse_target

#: a fault rig: its canonical endpoint (:func:`~hil.core.lock.lock_key`) and the unit id its URL names
RigKey = tuple[str, int]
RIG_TIMEOUT = 2.0  # seconds a rig has to answer recovery (a relay module answers at once)


def rig_key(url: str) -> RigKey:
    """The rig a URL reaches: one endpoint may serve several units (a gateway to modules on a serial line)."""
    return lock_key(url), int(str(parse_target(url).params.get("unit", 1)))


def rig_targets(profile: Any) -> dict[RigKey, frozenset[int]]:
    """The profile's Modbus fault rigs (``[faults.*] kind = "modbus-coil"``), each with the coils its injectors may
    switch (:attr:`~hil.families.fbs.injectors.modbus_coil.ModbusCoilSensorBreak.writable`): all recovery may
    put back there."""
    rigs: dict[RigKey, frozenset[int]] = {}
    for spec in profile.faults.values() if profile is not None else ():
        if spec.get("kind") == "modbus-coil" and "target" in spec:
            injector = ModbusCoilSensorBreak(str(spec["target"]), spec.get("first_coil", 0), coils=spec.get("coils"))
            key = rig_key(str(spec["target"]))
            rigs[key] = rigs.get(key, frozenset()) | injector.writable
    return rigs


def rig_steps(rigs: Mapping[RigKey, frozenset[int]], not_the_plc: Callable[[str], str | None]) \
        -> tuple[RecoveryStep, ...]:
    """The recovery step for a bench whose profile names ``rigs`` (:func:`rig_targets`); ``not_the_plc(target)``
    says why a rig may not be switched — it is the PLC under test, or that cannot be told
    (:func:`~hil.families.fbs.rig_identity.rig_refusal`); None once it is proven a separate device."""
    def step(journal: Journal, report: Recovery, by_hand: bool) -> None:
        restore_rig_coils(journal, report, by_hand, rigs, not_the_plc)
    return (step,)


def restore_rig_coils(journal: Journal, report: Recovery, by_hand: bool, rigs: Mapping[RigKey, frozenset[int]],
                      not_the_plc: Callable[[str], str | None]) -> None:
    """Each fault-rig coil a dead run switched, back to the state it held before (read back to verify) — only on
    one of the profile's ``rigs`` proven not to be the PLC under test, only a coil the profile lets that rig's
    injectors switch, and only while it still holds what the run switched it to — through the rig's guard
    (:meth:`hil.families.fbs.rig.GuardedRig.replay`)."""
    by_rig: dict[RigKey, dict[str, dict[str, Any]]] = {}
    for key, entry in journal.coils().items():
        why = COILS.check(entry) or age_problem(entry, by_hand)
        if why is None:
            try:
                rig = rig_key(entry["target"])
            except HilError as exc:  # a malformed URL is the entry's problem, not the recovery's end
                why = str(exc)
            else:
                if rig in rigs:
                    by_rig.setdefault(rig, {})[key] = entry
                    continue
                why = f"{entry['target']} is not a fault rig of this profile ([faults.*] kind = \"modbus-coil\")"
        report.refused.append(f"rig coil {key}: {why}")
    for rig, entries in by_rig.items():
        target = next(iter(entries.values()))["target"]
        why = not_the_plc(target)  # once per rig: the same endpoint and unit, however its entries spell it
        if why:
            report.refused += [f"rig coil {key}: {why}" for key in entries]
        else:
            _replay_on(target, rigs[rig], entries, journal, report)


def _replay_on(target: str, allowed: frozenset[int], entries: dict[str, dict[str, Any]], journal: Journal,
               report: Recovery) -> None:
    """``entries`` put back on the rig at ``target`` through a guard that allows exactly ``allowed``."""
    url = parse_target(target)
    link = None
    try:
        link = RigLink(rig_wire(url, RIG_TIMEOUT))
        GuardedRig(url, link, allowed, journal).replay(entries, report)
    except Exception as exc:  # noqa: BLE001 - every rig is tried; failures are listed
        report.failures += [f"rig coil {key} (original {int(e['original'])}): {exc}" for key, e in entries.items()]
    finally:
        if link is not None:
            link.close()


def recover(journal: Journal, transport: Any, timebase: Any, profile: Any = None) -> Recovery:
    """Replay ``journal`` onto the PLC behind ``transport`` (a command's direct transport) through the guard, under
    ``profile``'s allow-list and switches (without one nothing is replayed: everything is refused, by name)."""
    safety = profile.safety if profile is not None else None
    guard = GuardedTransport(transport, writable=safety.writable if safety else (),
                             volatile=safety.volatile if safety else ())
    guard.allow_destructive = bool(safety and safety.allow_destructive)
    guard.identity_vouched = bool(profile is not None and getattr(profile, "plc_id", None))
    guard.durable = journal
    plc = FbsPlc(transport, timebase)
    if profile is not None:
        plc.configure(profile.sections)
    # what the PLC rewrites itself (FUN86's outputs) and what causes it, as a run's bench knows it (bench.py):
    # causes are replayed first (hil.bench.replay.replay_elements)
    guard.side_effects = plc.pid.side_effects
    guard.clock = plc.rtc.clock()
    timeout = profile.timeout if profile is not None else RIG_TIMEOUT
    report = guard.recover(rig_steps(rig_targets(profile),
                                     lambda rig: rig_refusal(rig, journal.endpoint, transport, timeout)))
    assert report is not None  # a durable journal was given
    return report


__all__ = ["RigKey", "recover", "restore_rig_coils", "rig_key", "rig_steps", "rig_targets"]
