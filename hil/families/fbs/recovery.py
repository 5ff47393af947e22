"""Recovery first, the FBs side: a fault rig's coils, and recovery over a command's direct transport.

The rules — replay a dead run's journal before anything else, verify it, say so — are the guard's
(:meth:`hil.bench.guard.Guard.recover`).  This module adds what only an FBs bench has: the Modbus fault rig,
whose coils are put back (and read back) first, and :func:`recover` for the CLI's writing commands (``hil rtc
set``, ``hil drift measure --apply``), which hold a direct transport rather than a bench.
"""

from __future__ import annotations

from typing import Any

from hil.bench.guard import Recovery
from hil.core.errors import HilError
from hil.core.journal import Journal


def restore_rig_coils(journal: Journal, report: Recovery) -> None:
    """Each fault-rig coil a dead run switched, back to the state it held before (read back to verify)."""
    from hil.families.fbs.faults import ModbusCoilSensorBreak
    for key, entry in journal.coils().items():
        rig = ModbusCoilSensorBreak(entry["target"], entry["coil"])
        try:
            rig._write(0, bool(entry["value"]))
            if rig._read(entry["coil"]) != bool(entry["value"]):
                raise HilError("does not read back")
        except Exception as exc:  # noqa: BLE001 - every entry is tried; failures are listed
            report.failures.append(f"rig coil {key} (original {int(entry['value'])}): {exc}")
            continue
        finally:
            rig.close()
        journal.drop_coil(key)


def recover(journal: Journal, transport: Any, timebase: Any) -> Recovery:
    """Replay ``journal`` onto the PLC behind ``transport`` (a command's direct transport) through the guard."""
    from hil.families.fbs.device.plc import FbsPlc
    from hil.families.fbs.transport.guard import GuardedTransport
    guard = GuardedTransport(transport, writable=())  # restores only: nothing is written through its allow-list
    guard.durable = journal
    guard.clock = FbsPlc(transport, timebase).rtc.clock()
    report = guard.recover((restore_rig_coils,))
    assert report is not None  # a durable journal was given
    return report


__all__ = ["recover", "restore_rig_coils"]
