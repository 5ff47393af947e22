"""Recovery first, the FBs side: a fault rig's coils, and recovery over a command's direct transport.

The rules — replay a dead run's journal before anything else, only as far as it can be proven, verify it, say so —
are the guard's (:meth:`hil.bench.guard.Guard.recover`, :mod:`hil.bench.replay`).  This module adds what only an
FBs bench has: the Modbus fault rig, whose coils are put back (and read back) first — only on a rig the profile
names and proven not to be the PLC itself, and only while a coil still holds what the run switched it to — and
:func:`recover` for the CLI's writing commands (``hil rtc set``, ``hil drift measure --apply``), which hold a direct
transport rather than a bench.
"""

from __future__ import annotations

from typing import Any, Callable, Iterable

from hil.bench.guard import Recovery, RecoveryStep
from hil.bench.replay import age_problem
from hil.core.journal import COILS, Journal
from hil.core.lock import lock_key
from hil.families.fbs.injectors.modbus_coil import ModbusCoilSensorBreak
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.rig_identity import rig_refusal
from hil.families.fbs.transport.guard import GuardedTransport
from hil.io.url import parse_target


def rig_key(url: str) -> tuple[str, int]:
    """The rig a URL reaches: its canonical endpoint and unit id (one endpoint may serve several units)."""
    return lock_key(url), int(str(parse_target(url).params.get("unit", 1)))


def rig_targets(profile: Any) -> frozenset[str]:
    """The canonical endpoints of the profile's Modbus fault rigs (``[faults.*] kind = "modbus-coil"``)."""
    if profile is None:
        return frozenset()
    return frozenset(lock_key(str(spec["target"])) for spec in profile.faults.values()
                     if spec.get("kind") == "modbus-coil" and "target" in spec)


def rig_steps(rigs: Iterable[str], not_the_plc: Callable[[str], "str | None"]) -> tuple[RecoveryStep, ...]:
    """The recovery step for a bench whose profile names ``rigs``; ``not_the_plc(target)`` says why a rig target is
    the PLC under test (None when it is a separate device)."""
    allowed = frozenset(rigs)

    def step(journal: Journal, report: Recovery, by_hand: bool) -> None:
        restore_rig_coils(journal, report, by_hand, allowed, not_the_plc)
    return (step,)


def restore_rig_coils(journal: Journal, report: Recovery, by_hand: bool = False, rigs: frozenset[str] = frozenset(),
                      not_the_plc: Callable[[str], "str | None"] = lambda target: None) -> None:
    """Each fault-rig coil a dead run switched, back to the state it held before (read back to verify) — only on
    one of the profile's ``rigs``, and only while it still holds what the run switched it to — through the rig's
    guard (:meth:`hil.families.fbs.rig.GuardedRig.replay`)."""
    by_target: dict[str, dict[str, dict[str, Any]]] = {}
    for key, entry in journal.coils().items():
        why = COILS.check(entry) or age_problem(entry, by_hand)
        if why is None and lock_key(entry["target"]) not in rigs:
            why = f"{entry['target']} is not a fault rig of this profile ([faults.*] kind = \"modbus-coil\")"
        if why is None:
            why = not_the_plc(entry["target"])
        if why:
            report.refused.append(f"rig coil {key}: {why}")
            continue
        by_target.setdefault(entry["target"], {})[key] = entry
    for target, entries in by_target.items():
        rig = ModbusCoilSensorBreak(target, 0, journal=journal)
        try:
            rig.guard().replay(entries, report)
        except Exception as exc:  # noqa: BLE001 - every rig is tried; failures are listed
            report.failures += [f"rig coil {key} (original {int(e['original'])}): {exc}" for key, e in entries.items()]
        finally:
            rig.close()


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
    timeout = profile.timeout if profile is not None else 2.0
    report = guard.recover(rig_steps(rig_targets(profile),
                                     lambda rig: rig_refusal(rig, journal.endpoint, transport, timeout)))
    assert report is not None  # a durable journal was given
    return report


__all__ = ["recover", "restore_rig_coils", "rig_key", "rig_steps", "rig_targets"]
